"""``zswarm sweep`` (``python launch.py sweep``): run a grid of latency x dropout x seeds, distributed and simulated.

Each cell keeps its own directory (``DIR/cells/<cell>/``): the distributed run's ``run.rrd`` and
``run.json`` and the reference simulator's ``sim.json`` under the same faults and seed. A cell whose
summary exists is finished and is never run again, so an interrupted sweep resumes where it stopped.
At the end the sweep writes ``results.csv``, ``results.md`` (mean and spread over repeats),
``sweep.png`` (capture time and clearance against latency x dropout) and ``sweep.rrd`` (the metric
curves of every cell).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Sequence

from zswarm.args import (Parser, UsageError, add_law_arg, add_param_args, agent_count, loss_probabilities,
                         positive_int, renamed, safety_modes, seed_arg, sim_seconds)
from zswarm.files import out_dir, write_json
from zswarm.launch.chaos import parse_pause
from zswarm.launch.sweep import Cell, aggregate, cell_spec, run_cell_distributed, simulate_cells, write_curves, write_tables
from zswarm.swarm.faults import FaultModel, parse_duration_list

def build_parser(prog: str = "zswarm sweep") -> Parser:
    p = Parser(prog=prog, description="Sweep latency x dropout, distributed and simulated.")
    p.add_argument("--scenario", default="static-goal", help="a registered scenario or a .toml file "
                   "(default static-goal)")
    p.add_argument("--latency", default="0,50,100,200ms",
                   help="one-way latencies, a comma-separated list (default 0,50,100,200ms)")
    p.add_argument("--dropout", type=loss_probabilities, default=[0.0, 0.2, 0.5],
                   help="loss probabilities, a comma-separated list (default 0,0.2,0.5)")
    p.add_argument("--jitter", default="0", help="jitter of every cell, e.g. 10ms (default 0)")
    p.add_argument("--burst", type=float, default=0.0,
                   help="mean loss-burst length of every cell (default 0: independent)")
    p.add_argument("--safety", type=safety_modes, default=("barrier",), metavar="MODES",
                   help="safety filter modes, a comma-separated list of off and barrier: both side by side with "
                        "off,barrier (default barrier)")
    p.add_argument("--seeds", type=positive_int, default=3, metavar="K",
                   help="runs per cell, with seeds seed..seed+K-1 (default 3)")
    renamed(p, "--repeats", "runs per setting are --seeds K in every command")
    p.add_argument("--seed", type=seed_arg, default=0, help="repeat r uses seed + r (default 0)")
    p.add_argument("--agents", type=agent_count, default=None, help="N (default: the scenario's)")
    p.add_argument("--duration", type=sim_seconds, default=None, help="simulated seconds (default: the scenario's)")
    add_param_args(p)
    add_law_arg(p)
    p.add_argument("--out", type=Path, required=True, help="output directory (reused to resume)")
    p.add_argument("--sim-only", action="store_true", help="only the reference simulator (fast)")
    p.add_argument("--pause", type=parse_pause, action="append", default=[], metavar="WHAT@T:S",
                   help="freeze a process of every distributed run at T for S seconds (zswarm run --pause; "
                        "the simulation has no processes to pause)")
    return p


def parse_lists(args: argparse.Namespace) -> tuple[list[float], list[float], list[str]]:

    try:
        modes = list(args.safety)
        lat = parse_duration_list(args.latency)
        drop = list(args.dropout)
        for d in drop:
            FaultModel(dropout=d)
        FaultModel(burst=args.burst)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if not lat or not drop or not modes or args.seeds < 1:
        raise UsageError("give at least one latency, one dropout, one --safety mode and --seeds >= 1")
    return lat, drop, modes


def main(argv: Sequence[str] | None, prog: str = "zswarm sweep") -> int:
    args = build_parser(prog).parse_args(argv)
    lat, drop, modes = parse_lists(args)
    from zswarm.swarm.faults import parse_duration

    try:
        jitter = parse_duration(args.jitter)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    from zswarm.swarm.scenarios import get_scenario

    from zswarm.control.step import control_step
    from zswarm.paper.params import parse_assignments

    args.overrides = {**parse_assignments(args.assignments), **({"n_agents": args.agents} if args.agents is not None else {})}
    scenario = get_scenario(args.scenario, args.overrides)
    control_step([scenario], probe=True)  # a bad scenario, set or law stops here
    from zswarm.launch.plan import process_names

    names = process_names(("router", "world", "agents"), 1, range(scenario.n_agents))  # each cell's one run
    for pause in args.pause:  # each cell's run would refuse it: once, here
        if pause.what not in names:
            raise UsageError(f"--pause {pause}: a sweep's run has a world, a router and agents 0-{scenario.n_agents - 1}")
    if args.pause and args.sim_only:
        raise UsageError("--pause freezes a process of each distributed run: not with --sim-only")
    if args.out.exists() and not args.out.is_dir():
        raise UsageError(f"--out {args.out} is a file; give a directory (a new one, or a sweep's to resume it)")
    out_dir(args.out)
    cells = [Cell(la, d, r, m) for m in modes for la in lat for d in drop for r in range(args.seeds)]
    todo = [c for c in cells if not (args.out / "cells" / c.name / "sim.json").exists()
            or (not args.sim_only and not (args.out / "cells" / c.name / "run.json").exists())]
    print(f"sweep: {len(cells)} cells, {len(cells) - len(todo)} already finished", flush=True)
    start = time.monotonic()
    try:
        unsimulated = [c for c in todo if not (args.out / "cells" / c.name / "sim.json").exists()]
        for cell, summary in zip(unsimulated, simulate_cells(unsimulated, args, jitter)):
            (args.out / "cells" / cell.name).mkdir(parents=True, exist_ok=True)
            write_json(args.out / "cells" / cell.name / "sim.json", summary)
        for k, cell in enumerate(todo, 1):
            folder = args.out / "cells" / cell.name
            folder.mkdir(parents=True, exist_ok=True)
            if not args.sim_only and not (folder / "run.json").exists():
                run_cell_distributed(cell, args, folder, jitter)
            elapsed = time.monotonic() - start
            eta = elapsed / k * (len(todo) - k)
            bar = "#" * int(30 * k / len(todo))
            print(f"[{bar:<30}] {k}/{len(todo)} {cell.name}  elapsed {elapsed:.0f} s  ETA {eta:.0f} s", flush=True)
    except KeyboardInterrupt:
        print("sweep: interrupted; run the same command again to resume", file=sys.stderr, flush=True)
        return 130
    except RuntimeError as exc:
        print(f"sweep: {exc}", file=sys.stderr, flush=True)
        return 1
    sources = ("simulated",) if args.sim_only else ("distributed", "simulated")
    rows = aggregate(cells, args.out, sources)
    write_tables(rows, args.out)
    write_curves(cells, args, args.out, jitter)
    from zswarm.record.sweep_figure import save_figure

    d_m_ro = cell_spec(cells[0], args, jitter).scenario.params.margins.d_m_ro if cells else None
    save_figure(rows, args.out / "sweep.png", args.scenario, d_m_ro)
    print(f"sweep: wrote {args.out / 'results.md'}, {args.out / 'results.csv'}, {args.out / 'sweep.png'} and "
          f"{args.out / 'sweep.rrd'}")
    return 0
