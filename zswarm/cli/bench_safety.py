"""``zswarm bench safety``: the safety filter beside the law alone and ORCA, on the same runs.

Each scenario (its own set, ``--set`` overriding every run) on seeds 0..K-1 in the reference
simulator with fresh data, for each body and law asked, three ways: ``off`` (the law alone), ``barrier``
(zswarm's filter) and ``orca`` (RVO2 through ``pyrvo``, where it installs: :mod:`zswarm.bench.orca`; 2-D
point bodies only): collisions, the closest pair, runs that reached the goal or prey and the median time
they took, stalled agent-steps (the command cut under a tenth of the law's), and the simulator's time
per agent-step (the filter's cost is the barrier row's less the off row's).
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from zswarm.cli.bench_interactions import add_study_arguments, summarize
from zswarm.errors import UsageError

DESCRIPTION = __doc__.split("\n\n")[1]
MODES = ("off", "barrier", "orca")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenarios", type=lambda t: t.split(","), default=["goal-near-obstacle", "moving-prey"],
                   help="comma-separated registered scenarios (default goal-near-obstacle,moving-prey)")
    p.add_argument("--modes", type=lambda t: t.split(","), default=list(MODES),
                   help=f"comma-separated, of {', '.join(MODES)} (default all; orca needs pip install pyrvo)")
    p.add_argument("--bodies", type=lambda t: t.split(","), default=["point"],
                   help="comma-separated bodies (default point; orca runs point bodies only)")
    p.add_argument("--laws", default=None, help="comma-separated law names (default: each scenario's own)")
    add_study_arguments(p, "runs per scenario and mode", "n_agents=100")


def _run(task: tuple[str, str, int, dict[str, Any]]) -> dict[str, Any]:
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.sim.outcome import run_outcome

    name, mode, seed, extra = task
    scenario = get_scenario(name, extra)
    start = time.process_time()
    if mode == "orca":
        from zswarm.bench.orca import Orca

        orca = Orca(scenario.n_agents, scenario.params, scenario.dt, *scenario.obstacle_arrays())
        out = run_outcome(scenario, seed, shield=orca)
    else:
        out = run_outcome(scenario, seed, safety=mode)
    return {"scenario": name, "mode": mode, "seed": seed, "body": scenario.params.body.body,
            "law": scenario.params.law.law, "us_per_agent_step": (time.process_time() - start) * 1e6
            / (scenario.steps * scenario.n_agents), **out.to_dict()}


def run(args: argparse.Namespace) -> int:
    from multiprocessing import get_context

    from zswarm.bench.orca import available
    from zswarm.paper.params import parse_assignments
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.provenance import machine

    bad = [m for m in args.modes if m not in MODES]
    if bad:
        raise UsageError(f"--modes are {', '.join(MODES)} (got {', '.join(bad)})")
    modes = [m for m in args.modes if m != "orca" or available()]
    skipped = [m for m in args.modes if m not in modes]
    extra = parse_assignments(args.assignments)
    cases = []  # (scenario, its overrides, the modes it runs)
    for name in args.scenarios:
        for body in args.bodies:
            for law in args.laws.split(",") if args.laws else [""]:
                sets = {**extra, "body": body, **({"law": law} if law else {})}
                scenario = get_scenario(name, sets)  # bad input fails here
                point = scenario.dimensions == 2 and body == "point"
                cases.append((name, sets, [m for m in modes if m != "orca" or point]))
    start = time.time()
    tasks = [(name, mode, s, sets) for name, sets, ms in cases for mode in ms for s in range(args.seeds)]
    with get_context("fork").Pool(args.workers) as pool:
        runs = list(pool.imap_unordered(_run, tasks, chunksize=1))
    rows = []
    for name, sets, ms in cases:
        for mode in ms:
            mine = [r for r in runs if (r["scenario"], r["mode"], r["body"]) == (name, mode, sets["body"])
                    and (r["law"] == sets["law"] if "law" in sets else True)]
            rows.append({"scenario": name, "body": mine[0]["body"], "law": mine[0]["law"], "mode": mode,
                         **summarize(mine), "stalled_ticks": sum(r["safety_stalled_ticks"] for r in mine),
                         "us_per_agent_step": float(np.median([r["us_per_agent_step"] for r in mine]))})
    out = {"rows": rows, "seeds": args.seeds, "set": extra, "skipped": skipped, "machine": machine(),
           "seconds": time.time() - start}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{'scenario':<20} {'body':<17} {'law':<12} {'mode':<8} {'collisions':>10} {'closest':>8} {'reached':>7} "
          f"{'capture':>8} {'stalled':>9} {'us/step':>8}")
    for r in rows:
        cap = r["median_capture_time"]
        print(f"{r['scenario']:<20} {r['body']:<17} {r['law']:<12} {r['mode']:<8} {r['collisions']:>10} "
              f"{r['min_pair_distance']:>8.3f} {r['reached']:>3}/{r['runs']:<3} {'-' if cap is None else f'{cap:.1f}':>8} "
              f"{r['stalled_ticks']:>9} {r['us_per_agent_step']:>8.1f}")
    if skipped:
        print("skipped: orca (pip install pyrvo)")
    print(f"seeds 0-{args.seeds - 1}" + "".join(f", {k}={v}" for k, v in extra.items())
          + "; fresh data; capture in s; stalled in agent-steps; us/step: CPU microseconds per agent-step (median "
          + f"run); machine: {out['machine']}; {out['seconds']:.0f} s")
    return 0
