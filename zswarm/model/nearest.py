"""The closest parameter set that passes every design check (``zswarm design --nearest``)."""

from __future__ import annotations

import math

import numpy as np

from zswarm.model.design import check
from zswarm.model.params import FIELDS, Params

POTENTIAL_FIELDS = [name for name, spec in FIELDS.items() if spec.group == "potential"]


def nearest_passing(params: Params, factors: np.ndarray | None = None,
                    names: list[str] | None = None) -> tuple[Params, dict[str, float]] | None:
    """The closest parameter set that passes every check, changing one potential parameter, else two.

    Distance is sum |ln(new/old)| over the changed values (0 stays 0); the search tries each factor
    of ``factors`` on each name, then each pair of names. Returns (params, {name: new value}).
    """
    if factors is None:
        factors = np.exp(np.linspace(-np.log(20.0), np.log(20.0), 121))
    names = names or POTENTIAL_FIELDS
    base = params.flat()
    order = np.argsort(np.abs(np.log(factors)))
    best: tuple[float, dict[str, float]] | None = None

    def passes(change: dict[str, float]) -> bool:
        try:
            candidate = params.with_values(change)
        except ValueError:
            return False
        return check(candidate, swarm=False).failures() == ["swarm"] and check(candidate).ok

    for name in names:
        for f in factors[order]:
            change = {name: base[name] * float(f)}
            if passes(change):
                cost = abs(math.log(f))
                if best is None or cost < best[0]:
                    best = (cost, change)
                break
    if best is None:
        coarse = factors[order][::6]
        for i, a in enumerate(names):
            for b in names[i + 1:]:
                for fa in coarse:
                    for fb in coarse:
                        cost = abs(math.log(fa)) + abs(math.log(fb))
                        if best is not None and cost >= best[0]:
                            continue
                        change = {a: base[a] * float(fa), b: base[b] * float(fb)}
                        if passes(change):
                            best = (cost, change)
    if best is None:
        return None
    return params.with_values(best[1]), best[1]
