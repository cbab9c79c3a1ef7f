"""``zswarm bench net``: the distributed swarm's transport figures, with real processes on loopback.

Starts a router, the world and N agent processes in the ``bench-field`` setting (constant density:
the area grows with N, so each agent has about the same number of neighbours), runs them in free
mode and reports pose latency publish-to-neighbour (p50, p99), the share of control ticks on time,
pose messages received per agent per second (beside the poses in reach: what the agents in the
cells it listens to published, sampled by the world), the time until every agent is alive, and the
resident memory of an agent process.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from zswarm.paper.params import KINDS
from zswarm.args import agent_counts, law_name, positive_int, router_count, safety_mode_arg, sim_seconds
from zswarm.bench.figures import figure
from zswarm.bench.net import measure, record_curves
from zswarm.errors import UsageError
from zswarm.files import check_writable


DESCRIPTION = __doc__.split("\n\n")[1]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--agents", type=agent_counts,
                   default=[10], help="N, or a comma-separated list (default 10)")
    p.add_argument("--duration", type=sim_seconds, default=15.0,
                   help="simulated = wall seconds per run (default 15)")
    p.add_argument("--routers", type=router_count, default=1, metavar="K",
                   help="K meshed routers, agent i on router i mod K (default 1)")
    p.add_argument("--floor", action="store_true",
                   help="also run N bare Zenoh processes with the same traffic and report the agents' CPU "
                        "as a ratio to theirs")
    p.add_argument("--repeat", type=positive_int, default=1, metavar="K",
                   help="measure each N K times in turn (swarm, floors, swarm, ...) and report medians (default 1)")
    p.add_argument("--record", type=Path, default=None, metavar="FILE.rrd",
                   help="also write the curves (cost and latency against N) as a Rerun recording")
    p.add_argument("--safety", type=safety_mode_arg, default="barrier", metavar="off|barrier",
                   help="the agents' safety filter (default barrier, as runs): compare both for its cost")
    p.add_argument("--law", type=law_name, default="apf", help="the agents' control law (default apf; zswarm laws lists them)")
    p.add_argument("--body", choices=KINDS, default="point", help="the agents' body (default point)")
    p.add_argument("--compare", metavar="REF", default=None,
                   help="also run the agents of git ref REF (a commit, tag or branch of this clone), alternating "
                        "with this tree's, --repeat times each (at least 3), and print both sides' medians")
    p.add_argument("--json", action="store_true")


def run_compare(args: argparse.Namespace) -> int:
    """``--compare REF``: one N, the ref's agents and this tree's, alternately (:mod:`zswarm.bench.compare`)."""
    import sys

    from zswarm.bench.compare import compare, table
    from zswarm.provenance import machine

    if len(args.agents) != 1 or args.floor or args.record is not None:
        raise UsageError("--compare takes one N (--agents N) and neither --floor nor --record")
    argv = ["--agents", str(args.agents[0]), "--duration", f"{args.duration:g}", "--routers", str(args.routers),
            "--safety", args.safety, "--law", args.law]
    out = compare(args.compare, max(args.repeat, 3), argv, say=lambda line: print(line, file=sys.stderr, flush=True))
    out["settings"], out["machine"] = dict(zip(argv[::2], argv[1::2])), machine()
    print(json.dumps(out) if args.json else f"{table(out)}\n\n{' '.join(argv)}; machine: {out['machine']}")
    return 0


def run(args: argparse.Namespace) -> int:
    from zswarm.provenance import machine, versions

    if args.record is not None:
        check_writable(args.record, (".rrd",))
    from zswarm.laws.registry import bind
    from zswarm.swarm.scenarios import get_scenario

    bind(get_scenario("bench-field", {"law": args.law, "body": args.body}))  # a law that does not load: refused here, in one line
    if args.compare is not None:
        return run_compare(args)
    results = [measure(n, args.duration, args.floor, args.routers, args.repeat, args.safety, args.law, args.body)
               for n in args.agents]
    if args.record is not None:
        record_curves(results, args.record, {"agents": args.agents, "duration_s": args.duration, "floor": args.floor,
                                             "routers": args.routers, "repeat": args.repeat,
                                             "machine": machine(), "versions": versions()})
    if args.json:
        print(json.dumps(results[0] if len(results) == 1 else {"runs": results, "machine": machine()}))
        return 0
    for r in results:
        print(f"N={r['n_agents']:>4}  law {r.get('law')}  body {r.get('body')}  safety {r.get('safety')}  latency p50 {r['latency_ms']['p50']} ms  p99 {r['latency_ms']['p99']} ms  "
              f"age at use p99 {r['age_at_use_ms']['p99']} ms  on time {figure(r['on_time_ratio'], '.4f')}  "
              f"received/agent/s {figure(r['received_per_agent_per_s'], '.1f')} (in reach "
              f"{figure(r.get('in_reach_per_agent_per_s'), '.1f')})  startup {figure(r['startup_s'], '.2f')} s")
        print(f"        agent CPU {figure(r['cpu_ms_per_tick_agent'], '.2f')} ms/tick (max "
              f"{figure(r['cpu_ms_per_tick_agent_max'], '.2f')}), world {figure(r['cpu_share_world'], '.1%')} of a core, "
              f"routers ({r['routers']}) {figure(r['cpu_share_router'], '.1%')}; agent RSS {figure(r['rss_mb_per_agent'], '.1f')} MB, "
              f"PSS {figure(r['pss_mb_per_agent'], '.1f')} MB; world late ticks {r['world_late_ticks']}/{r['world_ticks']}")
        if "cpu_ms_per_tick_floor" in r:
            print(f"        floor CPU {figure(r['cpu_ms_per_tick_floor'], '.2f')} ms/tick with a ring channel "
                  f"(agent/floor {figure(r['cpu_ratio_agent_to_floor'], '.2f')}x), "
                  f"{figure(r['cpu_ms_per_tick_floor_callback'], '.2f')} ms/tick with a callback per sample "
                  f"(agent/floor {figure(r['cpu_ratio_agent_to_floor_callback'], '.2f')}x); router "
                  f"{figure(r['cpu_share_router_floor'], '.1%')}; floor PSS {figure(r['pss_mb_per_floor'], '.1f')} MB, "
                  f"RSS {figure(r['rss_mb_per_floor'], '.1f')} MB; {r['floor_alive']}/{r['n_agents']} alive")
        if r.get("repeats"):
            runs = ", ".join(f"{x:.2f}x" for x in r.get("cpu_ratio_agent_to_floor_runs", []) if x is not None)
            print(f"        medians of {r['repeats']} repeats" + (f"; agent/ring floor in each: {runs}" if runs else ""))
    print(f"machine: {machine()}")
    return 0
