"""``zswarm bench guidelines``: do the design checks predict what the swarm does?

Random parameter sets around each scenario's own, at each N, judged by ``zswarm design`` and simulated
on a few seeds: how many sets the checks pass that collide anyway (false-safe, the number that must be
0) and how many they fail that never collide (how conservative they are).

The study itself, and how its sets are drawn, is :mod:`zswarm.bench.guidelines`.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

from zswarm.args import UsageError, agent_counts, positive_float, positive_int, seed_arg
from zswarm.bench.guidelines import cases, run_study, table

DESCRIPTION = __doc__.split("\n\n")[1]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenarios", type=lambda t: t.split(","), default=["moving-prey", "large-swarm"],
                   help="comma-separated scenarios (default moving-prey,large-swarm)")
    p.add_argument("--agents", type=agent_counts, default=[10, 30, 100, 300], help="N values (default 10,30,100,300)")
    p.add_argument("--sets", type=positive_int, default=24, help="random sets per scenario and N (default 24)")
    p.add_argument("--seeds", type=positive_int, default=2, help="runs per set (default 2)")
    p.add_argument("--spread", type=positive_float, default=3.0,
                   help="each potential value is scaled by a factor in [1/S, S] (default 3)")
    p.add_argument("--seed", type=seed_arg, default=0, help="seed of the sampling (default 0)")
    p.add_argument("--workers", type=positive_int, default=os.cpu_count() or 1, help="processes (default: cores)")
    p.add_argument("--out", type=Path, default=None, metavar="DIR",
                   help="write study.json (every set and run) and guidelines.png there")
    p.add_argument("--json", action="store_true", help="print the table as JSON")


def run(args: argparse.Namespace) -> int:
    from zswarm.swarm.scenarios import SCENARIOS
    from zswarm.provenance import machine, versions

    for name in args.scenarios:
        if name not in SCENARIOS:
            raise UsageError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)}")
    if args.out is not None:
        from zswarm.files import check_writable, out_dir

        out_dir(args.out)
        check_writable(args.out / "study.json")
    start = time.time()
    todo = cases(args.scenarios, args.agents, args.sets, args.spread, args.seed)
    print(f"guidelines: {len(todo)} sets x {args.seeds} seeds on {args.workers} processes", file=sys.stderr,
          flush=True)
    rows = run_study(todo, args.seeds, args.workers,
                     lambda line: print(f"guidelines: {line}", file=sys.stderr, flush=True))
    result = {"table": table(rows), "settings": {k: (str(v) if isinstance(v, Path) else v)
                                                 for k, v in vars(args).items() if k != "run"},
              "machine": machine(), "versions": versions(), "seconds": time.time() - start}
    if args.out is not None:
        (args.out / "study.json").write_text(json.dumps({**result, "sets": rows}, indent=1))
        from zswarm.record.guidelines_figure import save_figure

        robot = rows[0]["params"]["robot_radius"] if rows else 0.05
        save_figure(result["table"], rows, args.out / "guidelines.png", 2.0 * float(robot))
    if args.json:
        print(json.dumps(result))
    else:
        print(render(result["table"]))
        print(f"machine: {result['machine']}; {result['seconds']:.0f} s")
    return 0


def render(rows: list[dict[str, Any]]) -> str:
    head = (f"{'scenario':<13} {'N':>4} {'sets':>5} {'pass':>5} {'FALSE-SAFE':>10} {'pass ok':>8} "
            f"{'fail coll':>9} {'conservative':>12} {'pass 1 group':>12} {'pass reached':>12}")
    lines = [head]
    for r in rows:
        lines.append(f"{r['scenario']:<13} {r['n'] or '':>4} {r['sets']:>5} {r['passed']:>5} {r['false_safe']:>10} "
                     f"{r['passed_clean']:>8} {r['failed_collided']:>9} {r['conservative']:>12} "
                     f"{r['passed_one_group']:>12} {r['passed_reached']:>12}")
    return "\n".join(lines)
