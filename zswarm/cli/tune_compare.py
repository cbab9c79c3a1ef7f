"""The chosen set against the starting set, on seeds the search never saw: in the batched simulator
(``held_out``), and as distributed swarms started with ``zswarm run`` (``confirm``). Both are judged by
the tune's own rule (:func:`zswarm.tune.objective.disqualified`)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from zswarm.model.params import Params
from zswarm.tune.space import TUNABLE


def held_out(task, sets: dict[str, Params], seeds: tuple[int, ...]) -> dict[str, dict[str, Any]]:
    """Each set on the held-out seeds: outcomes and their aggregate."""
    from zswarm.tune.objective import evaluate, run_score

    labels = list(sets)
    results = evaluate(task, [sets[k] for k in labels], seeds)
    out = {}
    for label, (value, outcomes, reasons) in zip(labels, results):
        out[label] = aggregate([o.to_dict() for o in outcomes], seeds, reasons,
                               [run_score(o, task) for o in outcomes], value)
    return out


def aggregate(runs: list[dict[str, Any]], seeds, reasons, scores, objective) -> dict[str, Any]:
    caught = [r["capture_time"] for r in runs if r["capture_time"] is not None]
    clearances = [r["min_obstacle_clearance"] for r in runs if r["min_obstacle_clearance"] is not None]
    return {"runs": len(runs), "captured": len(caught),
            "mean_capture_time": sum(caught) / len(caught) if caught else None,
            "mean_score": sum(scores) / len(scores) if scores else None, "objective": objective,
            "collisions": sum(r["collisions"] for r in runs),
            "obstacle_collisions": sum(r["obstacle_collisions"] for r in runs),
            "min_obstacle_clearance": min(clearances) if clearances else None,
            "min_pair_distance": min(r["min_pair_distance"] for r in runs),
            "disqualified": sum(r is not None for r in reasons),
            "per_seed": [{**r, "seed": s, "disqualified": why} for r, s, why in zip(runs, seeds, reasons)]}


def confirm(plan, args: argparse.Namespace, sets: dict[str, Params], faults, quiet: bool
            ) -> dict[str, dict[str, Any]]:
    """The sets as distributed swarms (``zswarm run``) on the first held-out seeds."""
    from zswarm.net.runspec import RunSpec
    from zswarm.tune.objective import disqualified

    folder: Path = plan.out / "confirm"
    folder.mkdir(exist_ok=True)
    seeds = plan.holdout[:args.confirm_seeds]
    out: dict[str, dict[str, Any]] = {}
    for label, params in sets.items():
        flat = params.flat()
        overrides = {**plan.overrides, **{n: flat[n] for n in TUNABLE}}
        runs = []
        for seed in seeds:
            name = f"{label}-seed{seed}"
            summary = folder / f"{name}.json"
            if not summary.exists():  # a finished confirmation run is never run again
                spec = RunSpec(run=f"tune-{name}", scenario_name=plan.scenario_name, overrides=tuple(overrides.items()),
                               seed=seed, potential=args.potential, duration=args.duration,
                               faults=dataclasses.replace(faults, seed=seed))
                if not quiet:
                    print(f"confirm: {label} set, seed {seed}, distributed ({spec.scenario.duration:g} s) ...",
                          file=sys.stderr, flush=True)
                cmd = [sys.executable, "-m", "zswarm", "run", *spec.to_argv(), "--record", str(folder / f"{name}.rrd"),
                       "--summary", str(folder / f"{name}.part.json"), "--quiet"]
                res = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                if res.returncode != 0:
                    raise RuntimeError(f"confirmation run {name}: zswarm run exited {res.returncode}: "
                                       f"{res.stderr.strip()[-300:]}")
                os.replace(folder / f"{name}.part.json", summary)
            runs.append(json.loads(summary.read_text()))
        reasons = [disqualified(r["collisions"], r["obstacle_collisions"], r["min_obstacle_clearance"], params)
                   for r in runs]
        scores = [r["capture_time"] if r["capture_time"] is not None
                  else r["duration"] + args.miss_penalty for r in runs]
        slim = [{k: r.get(k) for k in ("capture_time", "collisions", "obstacle_collisions", "min_obstacle_clearance",
                                       "min_pair_distance", "max_components")} for r in runs]
        out[label] = aggregate(slim, seeds, reasons, scores, None)
    return out
