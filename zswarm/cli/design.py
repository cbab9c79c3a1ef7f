"""``zswarm design``: judge a parameter set against the paper's guidelines before anything runs."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from zswarm.args import UsageError, add_param_args
from zswarm.model.design import DesignReport, check
from zswarm.model.nearest import Found, nearest_passing
from zswarm.model.params import DEFAULT_PARAMS, PAPER_PARAMS, Params, parse_assignments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_param_args(parser)
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
    parser.add_argument("--nearest", action="store_true",
                        help="also search the closest passing set (changing one or two potential values)")


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.4g}"
    return str(v)


def _paper(d: dict[str, Any] | None) -> str:
    if not d or "paper_holds" not in d:
        return ""
    return "holds" if d["paper_holds"] else "FAILS"


def _verdict(d: dict[str, Any]) -> str:
    if d.get("binding") is False:
        return "n/a"
    return "holds" if d["holds"] else "FAILS"


def render(report: DesignReport) -> str:
    prop3 = dict(report.prop3, paper_holds=report.prop3["holds"])
    rows = [
        ("Prop 1", report.prop1, f"c_g/c_o >= {_fmt(report.prop1['lower_bound'])}  "
                                 f"(d_0^go = {_fmt(report.prop1['d_0_go'])})"),
        ("Prop 2", report.prop2, f"c_g/c_o <= {_fmt(report.prop2['upper_bound'])}  "
                                 f"(exact {_fmt(report.prop2['exact_upper_bound'])}, "
                                 f"d_0^ro = {_fmt(report.prop2['d_0_ro'])})"),
        ("Prop 3", prop3, f"epsilon = {_fmt(report.prop3['epsilon'])}"),
        ("Prop 4", report.prop4, f"{_fmt(report.prop4['lhs'])} > {_fmt(report.prop4['rhs'])}"),
        ("Prop 5", report.prop5, f"{_fmt(report.prop5['lhs'])} > {_fmt(report.prop5['rhs'])}"),
        ("Formation", {"holds": report.formation["stable"], "detail": report.formation["detail"]},
         f"d^f = {_fmt(report.formation['equilibrium_spacing'])} "
         f"(eq 27: {_fmt(report.formation['closed_form_spacing'])})"),
        ("Contact", report.contact, f"{_fmt(report.contact['lhs'])} > {_fmt(report.contact['rhs'])}"),
        ("Swarm", report.swarm or {"holds": False, "detail": "not simulated: no stable pair spacing"},
         "closest pair " + _fmt((report.swarm or {}).get("min_pair_distance"))),
    ]
    if report.step is not None:
        rows.append(("Time step", report.step, f"2 v_max dt = {_fmt(report.step['step'])}"))
    if report.body is not None:
        rows.append(("Body", report.body, f"lag {_fmt(report.body['lag'])} vs slack {_fmt(report.body['slack'])}"))
    p = report.params.flat()
    lines = ["parameters: " + "  ".join(f"{k}={_fmt(v)}" for k, v in p.items()), "",
             f"the verdicts are for N = {report.params.swarm.n_agents} agents that sense within "
             f"R = {report.params.swarm.sensing_radius:g} under interaction {report.params.interaction.interaction}; "
             "'paper' is the paper's own verdict (every agent senses every other)", ""]
    lines.append(f"{'check':<10} {'verdict':<7} {'paper':<6} {'bound':<48} reason")
    for name, d, bound in rows:
        lines.append(f"{name:<10} {_verdict(d):<7} {_paper(d):<6} {bound:<48} {d['detail']}")
    lines += ["", "all guidelines hold" if report.ok else
              "guidelines fail: " + ", ".join(report.failures()),
              "the paper's guidelines: " + ("all hold" if not report.paper_failures() else
                                            "fail: " + ", ".join(report.paper_failures()))]
    return "\n".join(lines)


def judged(args: argparse.Namespace) -> tuple[Params, float | None]:
    """The set to judge, and the time step when it comes from a scenario."""
    if args.scenario is None:
        base = PAPER_PARAMS if args.paper else DEFAULT_PARAMS
        return base.with_overrides(args.assignments), None
    if args.paper:
        raise UsageError("--paper and --scenario both choose the set to start from; give one")
    from zswarm.model.scenarios import get_scenario

    scenario = get_scenario(args.scenario, parse_assignments(args.assignments))
    return scenario.params, scenario.dt


def _progress(line: str) -> None:
    print(f"nearest: {line}", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    params, dt = judged(args)
    from zswarm.files import check_writable
    from zswarm.record.design_figure import FORMATS

    for path, suffixes in ((args.save, (".rrd",)), (args.figure, FORMATS)):
        if path is not None:
            check_writable(path, suffixes)
    report = check(params, dt=dt)
    out: dict[str, Any] = report.to_json()
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
