"""``zswarm tune --confirm``: the chosen and the starting set as distributed swarms (``zswarm run``) on the
first held-out seeds, judged by the tune's own rule (:func:`zswarm.tune.objective.disqualified`)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from zswarm.paper.params import Params
from zswarm.tune.compare import aggregate
from zswarm.tune.space import TUNABLE


def confirm(plan, args: argparse.Namespace, sets: dict[str, Params], faults, quiet: bool
            ) -> dict[str, dict[str, Any]]:
    """The sets as distributed swarms (``zswarm run``) on the first held-out seeds."""
    from zswarm.launch.run_once import run_once
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
                run_once(spec, folder / f"{name}.rrd", summary, f"confirmation run {name}")
            runs.append(json.loads(summary.read_text()))
        reasons = [disqualified(r["collisions"], r["obstacle_collisions"], r["min_obstacle_clearance"], params)
                   for r in runs]
        scores = [r["capture_time"] if r["capture_time"] is not None
                  else r["duration"] + args.miss_penalty for r in runs]
        slim = [{k: r.get(k) for k in ("capture_time", "collisions", "obstacle_collisions", "min_obstacle_clearance",
                                       "min_pair_distance", "max_components")} for r in runs]
        out[label] = aggregate(slim, seeds, reasons, scores, None)
    return out
