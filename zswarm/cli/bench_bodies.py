"""``zswarm bench bodies``: what each body costs on the registered scenarios.

Each scenario's own set, with only the body changed (:mod:`zswarm.control.body`), run on seeds 0..K-1 in
the reference simulator: collisions, the closest two agents and an agent and an obstacle came, runs
that reached the goal or prey and the median time they took, against the point body (the paper's).
It also prints each set's body check (:mod:`zswarm.design.bodies`) beside what happened.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from zswarm.cli.bench_interactions import add_study_arguments, summarize

DESCRIPTION = __doc__.split("\n\n")[1]
SCENARIOS = ("static-goal", "moving-prey", "moving-prey-evasive", "moving-prey-blocked", "narrow-passage")
BODIES = ("point", "unicycle", "double-integrator")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenarios", type=lambda t: t.split(","), default=list(SCENARIOS),
                   help=f"comma-separated registered scenarios (default {','.join(SCENARIOS)})")
    p.add_argument("--bodies", type=lambda t: t.split(","), default=list(BODIES),
                   help=f"comma-separated (default {','.join(BODIES)})")
    add_study_arguments(p, "runs per scenario and body", "accel=1")


def _run(task: tuple[str, str, int, dict[str, Any]]) -> dict[str, Any]:
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.sim.outcome import run_outcome

    name, body, seed, extra = task
    scenario = get_scenario(name, {**extra, "body": body})
    return {"scenario": name, "body": body, "seed": seed, **run_outcome(scenario, seed).to_dict()}


def run(args: argparse.Namespace) -> int:
    from multiprocessing import get_context

    from zswarm.design.guidelines import check
    from zswarm.paper.params import parse_assignments
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.provenance import machine

    extra = parse_assignments(args.assignments)
    checks = {}
    for name in args.scenarios:
        for body in args.bodies:
            scenario = get_scenario(name, {**extra, "body": body})  # bad input fails here
            checks[name, body] = check(scenario.params, swarm=False).body
    start = time.time()
    tasks = [(name, body, s, extra) for name in args.scenarios for body in args.bodies for s in range(args.seeds)]
    with get_context("fork").Pool(args.workers) as pool:
        runs = list(pool.imap_unordered(_run, tasks, chunksize=1))
    rows = []
    for name in args.scenarios:
        for body in args.bodies:
            mine = [r for r in runs if r["scenario"] == name and r["body"] == body]
            clear = [r["min_obstacle_clearance"] for r in mine if r["min_obstacle_clearance"] is not None]
            rows.append({"scenario": name, "body": body, "body_check": checks[name, body]["holds"],
                         "min_obstacle_clearance": min(clear) if clear else None, **summarize(mine)})
    out = {"rows": rows, "seeds": args.seeds, "set": extra, "machine": machine(), "seconds": time.time() - start}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{'scenario':<20} {'body':<18} {'check':<6} {'collisions':>10} {'closest':>8} {'obstacle':>8} "
          f"{'contacts':>8} {'reached':>7} {'capture':>8} {'vs point':>8}")
    for r in rows:
        point = next((p for p in rows if p["scenario"] == r["scenario"] and p["body"] == "point"), None)
        cap = r["median_capture_time"]
        base = None if point is None else point["median_capture_time"]
        cost = "-" if cap is None or base is None else f"{cap - base:+.1f}"
        clear = "-" if r["min_obstacle_clearance"] is None else f"{r['min_obstacle_clearance']:.3f}"
        print(f"{r['scenario']:<20} {r['body']:<18} {'holds' if r['body_check'] else 'FAILS':<6} "
              f"{r['collisions']:>10} {r['min_pair_distance']:>8.3f} {clear:>8} {r['obstacle_contacts']:>8} "
              f"{r['reached']:>3}/{r['runs']:<3} {'-' if cap is None else f'{cap:.1f}':>8} {cost:>8}")
    print(f"seeds 0-{args.seeds - 1}" + "".join(f", {k}={v}" for k, v in extra.items())
          + f"; capture in s, 'vs point' the median's change; machine: {out['machine']}; {out['seconds']:.0f} s")
    return 0
