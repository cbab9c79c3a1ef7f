"""``zswarm bench placement``: how much neighbour traffic crosses between routers, by placement.

The reference simulator runs the scenario once (``--agents N``, ``--seed``); at evenly spaced instants
over the run, every pose an agent is handed by its cells (the agents' own rule) counts as crossing
when its sender runs on another of the ``--nodes K`` (equal capacities). Placement by space (a k-d
split of the spawn positions, as ``zswarm run --cluster`` places) against round-robin ids. A cluster
run reports the same figure as measured (``cross_router_share`` in its summary).
"""

from __future__ import annotations

import argparse
import json
import time

from zswarm.args import agent_count, positive_seconds, seed_arg, sim_seconds
from zswarm.errors import UsageError

DESCRIPTION = __doc__.split("\n\n")[1]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="large-swarm", help="registered scenario (default large-swarm)")
    p.add_argument("--agents", type=agent_count, default=1000, help="N (default 1000)")
    p.add_argument("--nodes", type=int, default=10, help="K nodes, equal capacities (default 10)")
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--samples", type=int, default=50, help="instants of the run counted (default 50)")
    p.add_argument("--duration", type=sim_seconds, default=None, help="simulated seconds (default the scenario's)")
    p.add_argument("--migrate-every", type=positive_seconds, default=10.0, metavar="S",
                   help="also count space placement with the agents moved every S seconds, as zswarm run "
                        "--migrate-every S moves them (default 10)")
    p.add_argument("--json", action="store_true", help="one JSON object: space, round_robin (the shares), ...")


def run(args: argparse.Namespace) -> int:
    from zswarm.bench.placement import placement_shares
    from zswarm.provenance import machine

    if args.agents < 2 or not 1 <= args.nodes <= args.agents:
        raise UsageError(f"--agents must be >= 2 and --nodes between 1 and N (got {args.agents}, {args.nodes})")
    if args.samples < 1 or (args.duration is not None and not args.duration > 0) or not args.migrate_every > 0:
        raise UsageError("--samples must be >= 1, and --duration and --migrate-every > 0")
    start = time.perf_counter()
    out = placement_shares(args.scenario, args.agents, args.nodes, args.seed, args.samples, args.duration,
                           args.migrate_every)
    out["seconds"], out["machine"] = time.perf_counter() - start, machine()
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{args.scenario}, N = {args.agents} over {args.nodes} nodes, seed {args.seed}, {out['samples']} instants "
          f"of {out['duration']:g} s: share of delivered poses that cross between routers")
    print(f"  space        {out['space']:.3f}")
    print(f"  round-robin  {out['round_robin']:.3f}")
    print(f"  space, moved every {args.migrate_every:g} s  {out['space_migrated']:.3f}   "
          f"({out['moves']} moves, {out['moves_per_agent']:.1f} per agent)")
    print(f"  (space, split anew at each instant: {out['space_replaced']:.3f})")
    print(f"  space / round-robin = {out['ratio']:.3f}; moved every {args.migrate_every:g} s / round-robin = "
          f"{out['ratio_migrated']:.3f}   ({out['seconds']:.1f} s)")
    print(f"machine: {out['machine']}")
    return 0
