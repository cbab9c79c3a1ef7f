"""``zswarm bench sim --batch B``: B runs stepped together against the same B runs one by one.

Both sides run in this one process, one after the other, on the same machine: run r is ``--scenario``
with seed r, and every second run goes through the faulty channel (``--latency``, ``--dropout``,
seeded by r), so the batch holds the mix a tuning search asks for. The figure is the ratio of the two
wall times (``simulate`` computes every metric of a summary each step; the batch only the six a search
needs), and, stricter, the ratio to the single runs' bare steps with no metric at all. The runs'
outcomes are compared as well: they must agree.
"""

from __future__ import annotations

import argparse
import json
import time

from zswarm.errors import UsageError
from zswarm.swarm.faults import FaultModel, parse_duration
from zswarm.swarm.scenarios import get_scenario
from zswarm.provenance import machine


def members(scenario_name: str, count: int, latency: float, dropout: float) -> list:
    from zswarm.sim.batch import Member

    scenario = get_scenario(scenario_name)
    try:
        faulty = [FaultModel(latency=latency, dropout=dropout, seed=r) for r in range(count)]
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    return [Member(scenario, r, faulty[r] if r % 2 else None) for r in range(count)]


def run_bench_batch(args: argparse.Namespace) -> int:
    from zswarm.sim.batch import simulate_batch
    from zswarm.sim.simulator import Simulator, simulate

    steps = args.steps or 200
    try:
        latency = parse_duration(args.latency)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    batch = members(args.scenario, args.batch, latency, args.dropout)
    start = time.perf_counter()
    together = simulate_batch(batch, steps).outcomes
    t_batch = time.perf_counter() - start
    start = time.perf_counter()
    alone = [simulate(m.scenario, m.seed, duration=steps * m.scenario.dt, faults=m.faults).summary for m in batch]
    t_alone = time.perf_counter() - start
    start = time.perf_counter()  # the strictest comparison: the single runs' bare step, no metrics at all
    for m in batch:
        sim = Simulator(m.scenario, m.seed, faults=m.faults)
        for _ in range(steps + 1):
            sim.advance(sim.command())
    t_bare = time.perf_counter() - start
    worst = max(abs(o.final_centroid_goal_distance - s["final_centroid_goal_distance"])
                for o, s in zip(together, alone))
    same = all(o.capture_time == s["capture_time"] and o.collisions == s["collisions"]
               for o, s in zip(together, alone)) and worst < 1e-9
    n = batch[0].scenario.n_agents
    out = {"scenario": args.scenario, "runs": args.batch, "n_agents": n, "steps": steps,
           "faulty_runs": sum(m.faulty for m in batch), "latency_ms": latency * 1000,
           "dropout": args.dropout, "batched_seconds": t_batch, "one_by_one_seconds": t_alone,
           "speedup": t_alone / t_batch, "batched_swarm_steps_per_second": args.batch * steps / t_batch,
           "one_by_one_swarm_steps_per_second": args.batch * steps / t_alone,
           "one_by_one_bare_seconds": t_bare, "speedup_over_bare": t_bare / t_batch,
           "outcomes_agree": same, "max_final_distance_difference": worst, "machine": machine()}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{args.batch} runs of {args.scenario} (N={n}, {steps} steps, {out['faulty_runs']} through "
              f"{out['latency_ms']:g} ms / {args.dropout:g} loss)")
        print(f"  batched     {t_batch:8.2f} s  {out['batched_swarm_steps_per_second']:10.0f} swarm-steps/s")
        print(f"  one by one  {t_alone:8.2f} s  {out['one_by_one_swarm_steps_per_second']:10.0f} swarm-steps/s")
        print(f"  one by one, bare steps (no metrics) {t_bare:8.2f} s  "
              f"{args.batch * steps / t_bare:10.0f} swarm-steps/s")
        print(f"  speed-up    {out['speedup']:8.1f} x  ({out['speedup_over_bare']:.1f} x over the bare steps)   "
              f"outcomes agree: {same} "
              f"(largest final-distance difference {worst:.1e})")
        print(f"machine: {out['machine']}")
    return 0 if same else 1
