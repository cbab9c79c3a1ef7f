"""The search space of ``zswarm tune``: some potential parameters, in log space, around a start.

A point x holds ln(value) of each tuned parameter; every other field keeps the scenario's value.
Log space because the parameters are strengths and ranges whose useful values span decades and whose
guidelines are ratios (c_g/c_o, c_o/l_o, ...): a step of 0.1 in x is a 10 % change at any scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zswarm.errors import UsageError
from zswarm.model.params import FIELDS, Params

TUNABLE = tuple(name for name, spec in FIELDS.items() if spec.group == "potential")
#: How far from its start each parameter may go: a factor of 20 either way.
SPAN = math.log(20.0)


@dataclass(frozen=True)
class Space:
    names: tuple[str, ...]
    base: Params  # the fixed fields, and the start of the tuned ones

    @classmethod
    def build(cls, names: list[str], base: Params) -> Space:
        unknown = [n for n in names if n not in TUNABLE]
        if unknown:
            raise UsageError(f"cannot tune {', '.join(unknown)}: tunable parameters are {', '.join(TUNABLE)} "
                             "(the swarm's own fields, such as v_max or sensing_radius, are given with --set)")
        if len(set(names)) != len(names) or not names:
            raise UsageError("--tune needs one or more distinct parameter names")
        zero = [n for n in names if base.flat()[n] <= 0]
        if zero:
            raise UsageError(f"cannot tune {', '.join(zero)} from 0 in log space; --set a value > 0 to start from")
        return cls(tuple(names), base)

    @property
    def start(self) -> np.ndarray:
        flat = self.base.flat()
        return np.log([float(flat[n]) for n in self.names])

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.start - SPAN, self.start + SPAN

    def values(self, x: np.ndarray) -> dict[str, float]:
        return {n: float(math.exp(v)) for n, v in zip(self.names, x)}

    def params(self, x: np.ndarray) -> Params:
        return self.base.with_values(self.values(x))


def only_apf(params: Params) -> None:
    """The search is apf's (its potential, within the design guidelines): another law is refused in one
    line that says whether it declares ranges a search could use."""
    law = params.law.law
    if law == "apf":
        return
    from zswarm.laws.registry import resolve

    ranges = resolve(law)[0].ranges
    raise UsageError(f"zswarm tune searches apf's potential within the design guidelines; law {law} "
                     + (f"declares ranges ({', '.join(ranges)}), but searching a law's own parameters is not "
                        "built yet: compare settings with zswarm bench laws --set law.NAME=VALUE" if ranges else
                        "declares no ranges for its parameters, so there is nothing to tune"))
