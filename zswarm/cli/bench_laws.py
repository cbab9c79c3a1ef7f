"""``zswarm bench laws``: the laws side by side on the same seeds and faults (:mod:`zswarm.bench.laws`)."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from zswarm.args import UsageError, agent_count, loss_probability, safety_modes, sim_seconds
from zswarm.cli.bench_interactions import add_study_arguments

DESCRIPTION = ("Every law (or those of --laws) on the same scenario, seeds and faults in the reference simulator, "
               "with the safety filter off and on: collisions, the closest pair, captures, order, groups, stalls "
               "and the filter's interventions.")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scenario", default="moving-prey", help="a registered scenario or .toml (default moving-prey)")
    p.add_argument("--agents", type=agent_count, default=None, help="N (default: the scenario's)")
    p.add_argument("--laws", default=None, help="comma-separated law names (default: every law zswarm laws lists)")
    p.add_argument("--latency", default="0,200ms", help="one-way latencies, comma-separated (default 0,200ms)")
    p.add_argument("--duration", type=sim_seconds, default=None, help="simulated seconds (default: the scenario's)")
    p.add_argument("--dropout", type=loss_probability, default=0.0, help="loss probability of every run (default 0)")
    p.add_argument("--safety", type=safety_modes, default=("off", "barrier"), metavar="MODES",
                   help="filter modes, comma-separated (default off,barrier)")
    p.add_argument("--figure", type=Path, default=None, metavar="FILE.png", help="write the figure here")
    p.add_argument("--force", action="store_true", help="overwrite --figure")
    add_study_arguments(p, "runs per row, seeds 0..K-1", "law.w_sep=2")


def run(args: argparse.Namespace) -> int:
    from multiprocessing import get_context

    from zswarm.bench.laws import Case, row, run_case, table
    from zswarm.files import check_writable
    from zswarm.laws.registry import bind, known
    from zswarm.swarm.faults import FaultModel, parse_duration_list
    from zswarm.paper.params import parse_assignments
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.provenance import machine

    extra = parse_assignments(args.assignments)
    laws = [x.strip() for x in args.laws.split(",") if x.strip()] if args.laws else known()
    try:
        latencies = parse_duration_list(args.latency)
        modes = list(args.safety)
        FaultModel(dropout=args.dropout)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    if args.figure is not None:
        if args.figure.exists() and not args.force:
            raise UsageError(f"{args.figure} exists; give --force to overwrite it")
        check_writable(args.figure, (".png", ".svg", ".pdf"))
    for law in laws:  # every mistake before a run starts
        bind(get_scenario(args.scenario, {**extra, "law": law, **({"n_agents": args.agents} if args.agents else {})}))
    start = time.time()
    if args.duration is not None and not 0 < args.duration < 1e6:
        raise UsageError(f"--duration must be a number of seconds > 0 (got {args.duration})")
    cases = [Case(args.scenario, law, lat, args.dropout, mode, seed, args.agents, tuple(extra.items()), args.duration)
             for law in laws for lat in latencies for mode in modes for seed in range(args.seeds)]
    with get_context("fork").Pool(args.workers) as pool:
        runs = pool.map(run_case, cases, chunksize=1)
    rows = [row([r for r in runs if r["law"] == law and r["latency"] == lat and r["safety"] == mode], args.dropout)
            for law in laws for lat in latencies for mode in modes]
    out = {"rows": rows, "scenario": args.scenario, "agents": args.agents, "seeds": args.seeds, "set": extra,
           "machine": machine(), "seconds": time.time() - start}
    if args.figure is not None:
        from zswarm.record.laws_figure import save_figure

        n = f", N = {args.agents}" if args.agents else ""
        save_figure(rows, args.figure, f"{args.scenario}{n}, seeds 0-{args.seeds - 1}, dropout {args.dropout:g}")
    if args.json:
        print(json.dumps(out))
        return 0
    print("\n".join(table(rows)))
    print(f"\n{args.scenario}{f', N = {args.agents}' if args.agents else ''}, seeds 0-{args.seeds - 1}, dropout "
          f"{args.dropout:g}; machine: {out['machine']}; {out['seconds']:.0f} s")
    return 0
