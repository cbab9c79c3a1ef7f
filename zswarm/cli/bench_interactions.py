"""``zswarm bench interactions``: each interaction on the same scenarios, sizes and seeds.

The scenario's own set at each N (grown by the rule of docs/scaling.md), with only the interaction
changed, run on seeds 0..K-1 in the reference simulator: collisions (events), the closest two agents
came, groups at the end, runs that reached the goal or prey, and the median nearest-neighbour spacing
at the end. This is the measurement the choice of ``scalable`` rests on (docs/scaling.md).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from typing import Any

import numpy as np

from zswarm.args import agent_counts, positive_float, positive_int

DESCRIPTION = __doc__.split("\n\n")[1]
DEFAULT = ("paper", "mean", "cutoff", "gate", "nearest", "mean+cutoff", "mean+gate", "mean+gate+cutoff")


def add_study_arguments(p: argparse.ArgumentParser, seeds_help: str, set_example: str) -> None:
    """What every study of many simulated runs takes: seeds, overrides, worker processes, JSON."""
    p.add_argument("--seeds", type=positive_int, default=5, help=f"{seeds_help} (default 5)")
    p.add_argument("--set", dest="assignments", action="append", default=[], metavar="NAME=VALUE",
                   help=f"override a parameter of every run (repeatable), e.g. --set {set_example}")
    p.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1, help="processes (default: cores)")
    p.add_argument("--json", action="store_true")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="large-swarm", help="a registered scenario (default large-swarm)")
    p.add_argument("--agents", type=agent_counts, default=[100],
                   help="N values (default 100)")
    p.add_argument("--interactions", type=lambda t: t.split(","), default=list(DEFAULT),
                   help=f"comma-separated (default {','.join(DEFAULT)})")
    p.add_argument("--duration-factor", type=positive_float, default=1.0, metavar="F",
                   help="run each for F times the scenario's own duration (default 1): how long a slow swarm "
                        "needs, without changing the scenario")
    add_study_arguments(p, "runs per interaction and N", "gate=0.7")


def _run(task: tuple[str, int, str, int, dict[str, Any], float]) -> dict[str, Any]:
    import dataclasses

    from zswarm.swarm.scenarios import get_scenario
    from zswarm.sim.outcome import run_outcome

    name, n, interaction, seed, extra, factor = task
    scenario = get_scenario(name, {**extra, "n_agents": n, "interaction": interaction})
    scenario = dataclasses.replace(scenario, duration=factor * scenario.duration)
    return {"n": n, "interaction": interaction, "seed": seed, **run_outcome(scenario, seed).to_dict()}


def summarize(runs: list[dict[str, Any]]) -> dict[str, Any]:
    caught = [r["capture_time"] for r in runs if r["capture_time"] is not None]
    return {"runs": len(runs), "collisions": sum(r["collisions"] for r in runs),
            "runs_with_collision": sum(r["collisions"] > 0 for r in runs),
            "min_pair_distance": min(r["min_pair_distance"] for r in runs),
            "one_group": sum(r["final_components"] == 1 for r in runs),
            "max_groups": max(r["final_components"] for r in runs),
            "reached": len(caught), "median_capture_time": float(np.median(caught)) if caught else None,
            "median_spacing": float(np.median([r["final_median_nearest"] for r in runs
                                               if r["final_median_nearest"] is not None])),
            "obstacle_contacts": sum(r["obstacle_collisions"] for r in runs),
            "final_distance": {"median": float(np.median([r["final_centroid_goal_distance"] for r in runs])),
                               "max": max(r["final_centroid_goal_distance"] for r in runs)}}


def run(args: argparse.Namespace) -> int:
    from multiprocessing import get_context

    from zswarm.paper.params import parse_assignments
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.provenance import machine

    extra = parse_assignments(args.assignments)
    for interaction in args.interactions:
        for n in args.agents:
            get_scenario(args.scenario, {**extra, "n_agents": n, "interaction": interaction})  # bad input fails here
    start = time.time()
    tasks = [(args.scenario, n, i, s, extra, args.duration_factor) for n in sorted(args.agents, reverse=True)
             for i in args.interactions for s in range(args.seeds)]
    with get_context("fork").Pool(args.workers) as pool:
        runs = list(pool.imap_unordered(_run, tasks, chunksize=1))
    rows = [{"scenario": args.scenario, "n": n, "interaction": i,
             **summarize([r for r in runs if r["n"] == n and r["interaction"] == i])}
            for n in args.agents for i in args.interactions]
    out = {"rows": rows, "seeds": args.seeds, "set": extra, "duration_factor": args.duration_factor,
           "machine": machine(), "seconds": time.time() - start}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{'N':>5} {'interaction':<18} {'collisions':>10} {'runs hit':>8} {'closest':>8} {'one group':>9} "
          f"{'reached':>7} {'capture':>8} {'spacing':>8}")
    for r in rows:
        cap = "-" if r["median_capture_time"] is None else f"{r['median_capture_time']:.1f}"
        print(f"{r['n']:>5} {r['interaction']:<18} {r['collisions']:>10} {r['runs_with_collision']:>8} "
              f"{r['min_pair_distance']:>8.3g} {r['one_group']:>5}/{r['runs']:<3} {r['reached']:>3}/{r['runs']:<3} "
              f"{cap:>8} {r['median_spacing']:>8.3f}")
    print(f"{args.scenario}, seeds 0-{args.seeds - 1}" + "".join(f", {k}={v}" for k, v in extra.items())
          + (f", {args.duration_factor:g} x its duration" if args.duration_factor != 1.0 else "")
          + f"; machine: {out['machine']}; {out['seconds']:.0f} s")
    return 0
