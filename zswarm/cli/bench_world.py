"""``zswarm bench world``: what the world process costs at N agents, and whether it keeps its pace.

Starts a router, the world (free clock, recording to a file) and crowd processes that carry N agents'
pose traffic (each agent at its spawn point, at the run's control rate; a small machine cannot hold N
agent processes at N = 1000), and reports the world's CPU (share of one core, and per pose taken in),
its late ticks, the poses it took in a second, and the router's and the crowds' CPU.
"""

from __future__ import annotations

import argparse
import json

from zswarm.net.runspec import time_scale_number
from zswarm.args import agent_counts, positive_int, sim_seconds
from zswarm.bench.figures import figure

DESCRIPTION = __doc__.split("\n\n")[1]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--agents", type=agent_counts, default=[100],
                   help="N, or a comma-separated list (default 100)")
    p.add_argument("--duration", type=sim_seconds, default=15.0, help="simulated seconds per run (default 15)")
    p.add_argument("--scenario", default="large-swarm", help="the run's scenario (default large-swarm)")
    p.add_argument("--time-scale", type=time_scale_number, default=1.0,
                   help="simulated seconds per wall second (default 1: the scenario's own rate)")
    p.add_argument("--crowds", type=positive_int, default=2,
                   help="processes that carry the agents' traffic (default 2)")
    p.add_argument("--intake", choices=("auto", "batch", "pose"), default="auto",
                   help="the world's --intake: a tick's poses at once, one at a time, or by N (default auto)")
    p.add_argument("--json", action="store_true")


def run(args: argparse.Namespace) -> int:
    from zswarm.bench.world_load import measure
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.provenance import machine

    get_scenario(args.scenario)  # an unknown scenario: one line, before anything starts
    results = [measure(n, args.duration, args.scenario, args.time_scale, args.crowds, args.intake) for n in args.agents]
    if args.json:
        print(json.dumps({"runs": results, "machine": machine()}))
        return 0
    for r in results:
        print(f"N={r['n_agents']:>5}  {r['scenario']} at {r['rate_hz']:g} Hz (time scale {r['time_scale']:g}, "
              f"intake {r['intake']}): "
              f"world {figure(r['world_cpu_share'], '.1%')} of a core, {figure(r['world_us_per_pose'], '.1f')} us a "
              f"pose; took in {r['poses_per_s_taken_in']:.0f} of {r['poses_per_s_sent']:.0f} poses/s; late ticks "
              f"{r['world_late_ticks']}/{r['world_ticks']}; router {figure(r['router_cpu_share'], '.1%')}, "
              f"crowds {figure(r['crowd_cpu_share'], '.1%')}; recording {r['recording_mb']:.1f} MB")
    print(f"machine: {machine()}")
    return 0
