"""The closest parameter set that passes every design check (``zswarm design --nearest``).

Distance is sum |ln(new/old)| over the potential values changed. The search:

1. for each potential value alone, the smallest change (factors up to 20 either way) that passes the
   analytic checks (Props 1-5, formation, contact: milliseconds each); the cheapest few of those
   through the swarm squeeze (a simulation, about a second at N = 100) until one passes;
2. for an interaction without the gate: ``interaction = scalable`` alone (no value changed), then
   step 1 with it (the law that keeps the goal's pull from piling up along chains);
3. the same over pairs of values on a coarser grid, with each interaction.

When nothing passes, :class:`NoPassingSet` says which check blocked every candidate and what would
lift it. ``progress`` (a callable taking one line) hears what the search is doing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from zswarm.design.guidelines import DesignReport, check
from zswarm.paper.params import FIELDS, Params

POTENTIAL_FIELDS = [name for name, spec in FIELDS.items() if spec.group == "potential"]
Progress = Callable[[str], None]

#: What lifts a check that blocks every candidate (said when nothing passes).
REMEDIES = {
    "prop1": "a goal near an obstacle needs more c_g/c_o (or a smaller d_m_go)",
    "prop2": "the goal pushes agents into obstacles: less c_g/c_o (or a smaller d_m_ro)",
    "prop3": "all-to-all cohesion needs sensing_radius >= 2 epsilon",
    "prop4": "the swarm's pull beats the obstacle: interaction=scalable (mean cohesion), a larger c_o/l_o "
             "or a smaller sensing_radius",
    "prop5": "the goal presses pairs together: a larger c_r, or interaction=scalable (the gate)",
    "formation": "the pair potential needs a stable spacing: attraction longer-ranged than repulsion "
                 "(l_a > l_r) and repulsion stronger at contact",
    "contact": "too many neighbours squeeze a touching pair: interaction=scalable, a larger c_r/l_r^2 or "
               "fewer agents within sensing_radius",
    "swarm": "the swarm crushes itself against an obstacle: interaction=scalable, or fewer agents",
    "step": "a smaller time step dt (or v_max)",
}


@dataclass(frozen=True)
class Found:
    params: Params
    change: dict[str, float | str]  # the values changed, by name
    cost: float
    report: DesignReport


@dataclass(frozen=True)
class NoPassingSet:
    blocking: tuple[str, ...]  # the checks that failed in every candidate tried
    tried: int

    def explain(self) -> str:
        what = "; ".join(f"{c}: {REMEDIES.get(c, '')}" for c in self.blocking)
        return f"no set within a factor of 20 of one or two values passes ({self.tried} tried); blocking: {what}"


def _factors() -> np.ndarray:
    f = np.exp(np.linspace(-np.log(20.0), np.log(20.0), 121))
    return f[np.argsort(np.abs(np.log(f)), kind="stable")]


def _cheap_candidates(params: Params, names: list[str], pairs: bool, dt: float | None,
                      blocked: dict[str, int]) -> list[tuple[float, dict[str, float]]]:
    """Changes that pass every check but the squeeze, cheapest first (the first per name, or per pair)."""
    base, factors = params.flat(), _factors()
    out: list[tuple[float, dict[str, float]]] = []

    def cheap_ok(change: dict[str, float]) -> bool:
        try:
            report = check(params.with_values(change), swarm=False, dt=dt)
        except ValueError:
            return False
        failed = [f for f in report.failures() if f != "swarm"]
        for f in failed:
            blocked[f] = blocked.get(f, 0) + 1
        blocked["_tried"] = blocked.get("_tried", 0) + 1
        return not failed and report.formation["stable"]

    if not pairs:
        for name in names:
            for f in factors[1:]:  # factors[0] is 1: no change
                change = {name: float(base[name]) * float(f)}
                if cheap_ok(change):
                    out.append((abs(math.log(f)), change))
                    break
    else:
        coarse = factors[6::6]
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                best = None
                for fa in coarse:
                    for fb in coarse:
                        cost = abs(math.log(fa)) + abs(math.log(fb))
                        if best is not None and cost >= best[0]:
                            continue
                        change = {a: float(base[a]) * float(fa), b: float(base[b]) * float(fb)}
                        if cheap_ok(change):
                            best = (cost, change)
                if best is not None:
                    out.append(best)
    return sorted(out, key=lambda c: c[0])


def nearest_passing(params: Params, dt: float | None = None, progress: Progress | None = None,
                    names: list[str] | None = None, squeezes: int = 4) -> Found | NoPassingSet:
    """The closest set that passes every check (see the module doc); at most ``squeezes`` swarm
    simulations per phase, cheapest candidates first."""
    say = progress or (lambda line: None)
    names = names or [n for n in POTENTIAL_FIELDS if float(params.flat()[n]) > 0.0]
    blocked: dict[str, int] = {}
    switched = None if params.interaction.spec.gate else params.with_values({"interaction": "scalable"})
    label = lambda base: "" if base is params else f" with interaction={base.interaction.interaction}"  # noqa: E731

    def search(base: Params, pairs: bool) -> Found | None:
        say(f"{'two values' if pairs else 'one value'} at a time{label(base)}: the analytic checks")
        candidates = _cheap_candidates(base, names, pairs, dt, blocked)[:squeezes]
        for k, (cost, change) in enumerate(candidates, 1):
            say(f"  squeeze {k}/{len(candidates)}: " + ", ".join(f"{n}={v:.4g}" for n, v in change.items()))
            report = check(base.with_values(change), dt=dt)
            if report.ok:
                if base is not params:
                    change = {"interaction": base.interaction.interaction, **change}
                return Found(base.with_values(change), change, cost, report)
            blocked["swarm"] = blocked.get("swarm", 0) + 1
        return None

    phases: list[tuple[Params, bool] | Params] = [(params, False)]
    if switched is not None:
        phases += [switched, (switched, False)]
    phases += [(params, True)] + ([(switched, True)] if switched is not None else [])
    for phase in phases:
        if isinstance(phase, Params):
            say(f"interaction={phase.interaction.interaction} alone")
            report = check(phase, dt=dt)
            if report.ok:
                return Found(phase, {"interaction": phase.interaction.interaction}, 0.0, report)
            for f in report.failures():
                blocked[f] = blocked.get(f, 0) + 1
            continue
        found = search(*phase)
        if found is not None:
            return found
    tried = blocked.pop("_tried", 0)
    top = max(blocked.values(), default=0)
    return NoPassingSet(tuple(k for k, v in sorted(blocked.items(), key=lambda kv: -kv[1]) if v == top), tried)
