"""``zswarm design``: judge a parameter set against the paper's guidelines before anything runs."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from zswarm.args import UsageError, add_law_arg, add_param_args
from zswarm.design.guidelines import check, coverage
from zswarm.design.text import render
from zswarm.design.nearest import Found, nearest_passing
from zswarm.paper.params import DEFAULT_PARAMS, PAPER_PARAMS, Params, parse_assignments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_param_args(parser)
    add_law_arg(parser)
    parser.add_argument("--paper", action="store_true",
                        help="start from the paper's printed values instead of zswarm's defaults")
    parser.add_argument("--scenario", metavar="NAME|FILE.toml",
                        help="judge that scenario's own set (at the N of --set n_agents=N, grown by the rule of "
                             "docs/scaling.md) and its time step")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    parser.add_argument("--save", metavar="FILE.rrd", type=Path,
                        help="write the design view (the figure of --figure and the verdict table) to a Rerun "
                             "recording")
    parser.add_argument("--figure", metavar="FILE.png|svg|pdf", type=Path,
                        help="write Fig 9 (Prop 1), the Prop 2 bound and the pair force as plots with labelled "
                             "axes, each bound marked with its exact value, and the verdicts as a table")
    parser.add_argument("--force", action="store_true", help="overwrite an existing --figure or --save file")
    parser.add_argument("--nearest", action="store_true",
                        help="also search the closest passing set (changing one or two potential values)")


def judged(args: argparse.Namespace) -> tuple[Params, float | None]:
    """The set to judge, and the time step when it comes from a scenario."""
    if args.scenario is None:
        base = PAPER_PARAMS if args.paper else DEFAULT_PARAMS
        return base.with_overrides(args.assignments), None
    if args.paper:
        raise UsageError("--paper and --scenario both choose the set to start from; give one")
    from zswarm.swarm.scenarios import get_scenario

    scenario = get_scenario(args.scenario, parse_assignments(args.assignments))
    return scenario.params, scenario.dt


def _progress(line: str) -> None:
    print(f"nearest: {line}", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    params, dt = judged(args)
    guided, note = coverage(params)
    if guided is None:  # Propositions 1-5 are the paper's law's
        print(json.dumps({"ok": None, "law": params.law.law, "note": note}) if args.json else note)
        return 0
    params = guided  # a mixed swarm: the agents they cover, among themselves (said below)
    from zswarm.files import check_writable
    from zswarm.record.design_figure import FORMATS

    for path, suffixes in ((args.save, (".rrd",)), (args.figure, FORMATS)):
        if path is not None:
            if path.is_file() and not args.force:
                raise UsageError(f"{path} exists; give another path or --force")
            check_writable(path, suffixes)
    report = check(params, dt=dt)
    out: dict[str, Any] = {**report.to_json(), **({"covers": note} if note else {})}
    nearest = None
    if args.nearest and not report.ok:
        nearest = nearest_passing(params, dt=dt, progress=_progress)
        out["nearest"] = ({"params": nearest.params.flat(), "changed": nearest.change, "ok": nearest.report.ok}
                          if isinstance(nearest, Found) else
                          {"params": None, "ok": False, "blocking": list(nearest.blocking),
                           "explain": nearest.explain()})
    if args.save is not None:
        from zswarm.record.design_plots import save_design

        save_design(report, args.save)
    if args.figure is not None:
        from zswarm.record.design_figure import save_figure

        save_figure(report, args.figure)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(render(report))
        if note:
            print(f"note: {note}")
        if args.nearest and not report.ok:
            if isinstance(nearest, Found):
                print("nearest passing set: " + "  ".join(
                    f"--set {k}={v}" if isinstance(v, str) else f"--set {k}={v:.4g}" for k, v in nearest.change.items()))
            else:
                print("nearest passing set: none found: " + nearest.explain())
        if args.save is not None:
            print(f"saved the design view to {args.save} (open with: rerun {args.save})")
        if args.figure is not None:
            print(f"saved the figure to {args.figure}")
    return 0 if report.ok else 1
