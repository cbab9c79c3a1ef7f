"""A design report as the text table ``zswarm design`` prints (and ``zswarm tune`` writes to design.txt)."""

from __future__ import annotations

import math
from typing import Any

from zswarm.design.guidelines import DesignReport


def _fmt(v: Any) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.4g}"
    return str(v)


def _paper(name: str, d: dict[str, Any] | None) -> str:
    """The paper's own verdict: for its Propositions only (the other rows are checks of ours)."""
    if not name.startswith("Prop ") or not d:
        return ""
    return "holds" if d.get("paper_holds", d["holds"]) else "FAILS"


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
    if report.safety is not None:
        s = report.safety
        bound = "-" if s["distance"] is None else f"D_s = {_fmt(s['distance'])}, data age <= {_fmt(max(s['max_age'], 0.0))} s"
        rows.append(("Safety", s, bound))
    p = report.params.flat()
    lines = ["parameters: " + "  ".join(f"{k}={_fmt(v)}" for k, v in p.items()), "",
             f"the verdicts are for N = {report.params.swarm.n_agents} agents that sense within "
             f"R = {report.params.swarm.sensing_radius:g} under interaction {report.params.interaction.interaction}; "
             "'paper' is the paper's own verdict (every agent senses every other)", ""]
    lines.append(f"{'check':<10} {'verdict':<7} {'paper':<6} {'bound':<48} reason")
    for name, d, bound in rows:
        lines.append(f"{name:<10} {_verdict(d):<7} {_paper(name, d):<6} {bound:<48} {d['detail']}")
    paper = report.paper_failures()
    lines += ["", "verdict: " + ("all checks hold" if report.ok else "fails " + ", ".join(report.failures())),
              "paper:   its Propositions 1-5 as printed " + ("all hold" if not paper else "fail: " + ", ".join(paper))
              + " (the 'paper' column)"]
    return "\n".join(lines)
