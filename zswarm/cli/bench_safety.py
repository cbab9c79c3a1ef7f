"""``zswarm bench safety``: the safety filter beside the law alone and ORCA, on the same runs.

Each scenario (its own set, ``--set`` overriding every run) on seeds 0..K-1 in the reference
simulator with fresh data, three ways: ``off`` (the law alone), ``barrier`` (zswarm's filter) and
``orca`` (RVO2 through ``pyrvo``, where it installs: :mod:`zswarm.bench.orca`): collisions, the closest
pair, runs that reached the goal or prey and the median time they took, and stalled agent-steps (the
command cut under a tenth of the law's). 2-D point bodies.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from zswarm.cli.bench_interactions import add_study_arguments, summarize
from zswarm.errors import UsageError

DESCRIPTION = __doc__.split("\n\n")[1]
MODES = ("off", "barrier", "orca")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenarios", type=lambda t: t.split(","), default=["goal-near-obstacle", "moving-prey"],
                   help="comma-separated registered scenarios (default goal-near-obstacle,moving-prey)")
    p.add_argument("--modes", type=lambda t: t.split(","), default=list(MODES),
                   help=f"comma-separated, of {', '.join(MODES)} (default all; orca needs pip install pyrvo)")
    add_study_arguments(p, "runs per scenario and mode", "n_agents=100")


def _run(task: tuple[str, str, int, dict[str, Any]]) -> dict[str, Any]:
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.sim.outcome import run_outcome

    name, mode, seed, extra = task
    scenario = get_scenario(name, extra)
    start = time.time()
    if mode == "orca":
        from zswarm.bench.orca import Orca

        orca = Orca(scenario.n_agents, scenario.params, scenario.dt, *scenario.obstacle_arrays())
        out = run_outcome(scenario, seed, shield=orca)
    else:
        out = run_outcome(scenario, seed, safety=mode)
    return {"scenario": name, "mode": mode, "seed": seed, "seconds": time.time() - start, **out.to_dict()}


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
    for name in args.scenarios:
        scenario = get_scenario(name, extra)  # bad input fails here
        if scenario.dimensions != 2 or scenario.params.body.body != "point":
            raise UsageError(f"bench safety compares 2-D point bodies ({name} is not one)")
    start = time.time()
    tasks = [(name, mode, s, extra) for name in args.scenarios for mode in modes for s in range(args.seeds)]
    with get_context("fork").Pool(args.workers) as pool:
        runs = list(pool.imap_unordered(_run, tasks, chunksize=1))
    rows = []
    for name in args.scenarios:
        for mode in modes:
            mine = [r for r in runs if r["scenario"] == name and r["mode"] == mode]
            rows.append({"scenario": name, "mode": mode, **summarize(mine),
                         "stalled_ticks": sum(r["safety_stalled_ticks"] for r in mine),
                         "seconds_per_run": sum(r["seconds"] for r in mine) / len(mine)})
    out = {"rows": rows, "seeds": args.seeds, "set": extra, "skipped": skipped, "machine": machine(),
           "seconds": time.time() - start}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{'scenario':<20} {'mode':<8} {'collisions':>10} {'closest':>8} {'reached':>7} {'capture':>8} "
          f"{'stalled':>9} {'s/run':>6}")
    for r in rows:
        cap = r["median_capture_time"]
        print(f"{r['scenario']:<20} {r['mode']:<8} {r['collisions']:>10} {r['min_pair_distance']:>8.3f} "
              f"{r['reached']:>3}/{r['runs']:<3} {'-' if cap is None else f'{cap:.1f}':>8} {r['stalled_ticks']:>9} "
              f"{r['seconds_per_run']:>6.1f}")
    if skipped:
        print("skipped: orca (pip install pyrvo)")
    print(f"seeds 0-{args.seeds - 1}" + "".join(f", {k}={v}" for k, v in extra.items())
          + f"; fresh data; capture in s; stalled in agent-steps; machine: {out['machine']}; {out['seconds']:.0f} s")
    return 0
