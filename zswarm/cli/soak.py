"""``zswarm bench soak``: a long run under loss, watched for leaks and a growing backlog
(:mod:`zswarm.bench.soak` runs and judges it; this prints it)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from zswarm.args import agent_count, loss_probability, renamed, seed_arg, wall_seconds
from zswarm.bench.figures import figure
from zswarm.bench.soak import FLAT_MB_PER_MIN, run_soak


DESCRIPTION = ("N agents on bench-field with seeded loss for several minutes; samples every process's memory and "
               "the agents' inbound queues and tick lag. Exit 1 when memory or backlog grows.")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--agents", type=agent_count, default=30, help="N (default 30)")
    p.add_argument("--dropout", type=loss_probability, default=0.2, help="loss probability per message (default 0.2)")
    p.add_argument("--stop-after", type=wall_seconds, default=300.0, metavar="S",
                   help="wall-clock time, e.g. 300 or 5min (default 300 s)")
    renamed(p, "--duration", "the soak's length is wall-clock time: give --stop-after S")
    p.add_argument("--seed", type=seed_arg, default=0)
    p.add_argument("--json", action="store_true")


def run(args: argparse.Namespace) -> int:
    from zswarm.provenance import machine

    r = run_soak(args.agents, args.dropout, args.stop_after, seed=args.seed)
    r["machine"] = machine()
    if args.json:
        print(json.dumps(r))
    else:
        print_report(r)
    return 0 if r["memory_flat"] and r["backlog_flat"] else 1


def print_report(r: dict[str, Any]) -> None:
    """The soak's figures as text; a figure the run did not produce prints as n/a."""
    m, b, s = r["memory"], r["backlog"], r["run"]
    print(f"soak: {r['n_agents']} agents, dropout {r['dropout']}, {r['duration_s']:.0f} s "
          f"(warm-up {r['warmup_s']:.0f} s), seed {r['seed']}")
    print(f"memory: agent RSS median {figure(m['agent_rss_mb_median'], '.1f')} MB; slope median "
          f"{figure(m['agent_slope_mb_per_min_median'], '+.3f')} MB/min, max "
          f"{figure(m['agent_slope_mb_per_min_max'], '+.3f')} MB/min; largest growth "
          f"{figure(m['agent_growth_mb_max'], '+.2f')} MB")
    for name in ("world", "router"):
        if m[name]:
            print(f"        {name}: {m[name]['first_mb']:.1f} -> {m[name]['last_mb']:.1f} MB "
                  f"({m[name]['slope_mb_per_min']:+.3f} MB/min)")
    print(f"backlog: inbound queue p99 {figure(b['queue_p99_first_half'], '.0f')} -> "
          f"{figure(b['queue_p99_second_half'], '.0f')}; tick lag p99 {figure(b['tick_lag_p99_ms_first_half'], '.1f')}"
          f" -> {figure(b['tick_lag_p99_ms_second_half'], '.1f')} ms; late ticks "
          f"{figure(b['late_share_first_half'], '.3%')} -> {figure(b['late_share_second_half'], '.3%')} "
          f"(first -> second half)")
    print(f"run: on time {s['on_time_ratio']}, observed dropout {s['observed_dropout']}, collisions "
          f"{s['collisions']}, pose latency {s['pose_latency_ms']}")
    print(f"verdict: memory {'flat' if r['memory_flat'] else 'GROWING'} (every process < {FLAT_MB_PER_MIN} MB/min), "
          f"backlog {'flat' if r['backlog_flat'] else 'GROWING'}")
    print(f"machine: {r['machine']}")
