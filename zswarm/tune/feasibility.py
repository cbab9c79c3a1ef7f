"""How far a parameter set is from passing ``zswarm design``: 0 when it passes, more the further off.

:func:`violation` turns each failed check of a :class:`~zswarm.design.guidelines.DesignReport` into a
positive amount (mostly the log of the ratio by which the inequality fails), so a search that starts
outside the allowed region is led into it. The cheap checks (Props 1-5, formation, contact) run first;
the swarm squeeze (a simulation, about a second) only for a set that passes them all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from zswarm.design.guidelines import DesignReport, check, has_guidelines
from zswarm.paper.params import Params

CHECKS = ("prop1", "prop2", "prop3", "prop4", "prop5", "formation", "contact", "swarm")
#: What a failed check that has no graded measure counts (no stable spacing, say).
FLAT = 5.0
#: The least a failed check counts, so a set that misses by a hair still counts as failing.
TINY = 1e-6


def _log_ratio(need: float | None, have: float | None) -> float:
    """ln(need/have) for 'have >= need', with the degenerate cases made large."""
    if need is None or have is None or not math.isfinite(need):
        return FLAT
    if have <= 0:
        return FLAT if need > 0 else TINY
    return math.log(need / have) if need > 0 else TINY


def amounts(report: DesignReport) -> dict[str, float]:
    """The violation of every failed check (checks that hold are absent)."""
    out: dict[str, float] = {}
    p1, p2, p3, p4, p5 = report.prop1, report.prop2, report.prop3, report.prop4, report.prop5
    ratio = report.params.potential.c_g / report.params.potential.c_o
    if not p1["holds"]:
        out["prop1"] = _log_ratio(p1["lower_bound"], ratio)
    if not p2["holds"]:
        out["prop2"] = _log_ratio(ratio, p2["upper_bound"])
    if not p3["holds"] and p3.get("binding", True):
        out["prop3"] = _log_ratio(2.0 * p3["epsilon"], report.params.swarm.sensing_radius)
    if not p4["holds"]:
        out["prop4"] = _log_ratio(p4["rhs"], p4["lhs"])
    if not p5["holds"]:
        out["prop5"] = _log_ratio(p5["rhs"], p5["lhs"])
    if not report.formation["stable"]:
        out["formation"] = FLAT
    if not report.contact["holds"]:
        lhs, rhs = report.contact["lhs"], report.contact["rhs"]
        out["contact"] = _log_ratio(rhs, lhs) if lhs > 0 else 1.0 + (rhs - lhs) / rhs
    if report.swarm is not None and not report.swarm["holds"]:
        s = report.swarm
        out["swarm"] = (max(_log_ratio(s["required_pair_distance"], s["min_pair_distance"]), 0.0)
                        + max(_log_ratio(report.params.margins.d_m_ro, s["min_obstacle_distance"]), 0.0))
    return {k: max(v, TINY) for k, v in out.items()}


@dataclass(frozen=True)
class Verdict:
    violation: float  # 0: passes every check that is not waived
    failures: tuple[str, ...]  # every failed check, waived ones included
    report: DesignReport | None  # None: a law the guidelines do not cover
    squeezed: bool  # whether the swarm squeeze ran


def judge(params: Params, waived: frozenset[str] = frozenset()) -> Verdict:
    """Check ``params`` (the squeeze only when everything else that counts passes). A law other than
    apf has no guidelines: every set of it is feasible, and the safety filter and the objective's
    disqualifications are what keep it apart."""
    if not has_guidelines(params.law.law):
        return Verdict(violation=0.0, failures=(), report=None, squeezed=False)
    report = check(params, swarm=False)
    counted = {k: v for k, v in amounts(report).items() if k not in waived and k != "swarm"}
    squeezed = False
    if not counted and "swarm" not in waived:
        report, squeezed = check(params), True
        counted = {k: v for k, v in amounts(report).items() if k not in waived}
    failed = set(report.failures())
    if not squeezed and report.formation["stable"]:
        failed.discard("swarm")  # not run: something cheaper failed first (or it is waived)
    return Verdict(violation=float(sum(counted.values())), failures=tuple(k for k in CHECKS if k in failed),
                   report=report, squeezed=squeezed)
