"""The search space of ``zswarm tune``: some potential parameters, in log space, around a start; or,
for a law other than apf, the parameters it declares ``ranges`` for.

A point x holds ln(value) of each tuned parameter; every other field keeps the scenario's value.
Log space because the parameters are strengths and ranges whose useful values span decades and whose
guidelines are ratios (c_g/c_o, c_o/l_o, ...): a step of 0.1 in x is a 10 % change at any scale. A
law's own parameters are searched within the ranges the law declares, each mapped onto [0, 1] (a range
may start at 0, where a log space cannot), so a step of 0.1 is a tenth of its range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zswarm.errors import UsageError
from zswarm.paper.params import FIELDS, Params

TUNABLE = tuple(name for name, spec in FIELDS.items() if spec.group == "potential")
#: How far from its start each parameter may go: a factor of 20 either way.
SPAN = math.log(20.0)


@dataclass(frozen=True)
class Space:
    names: tuple[str, ...]
    base: Params  # the fixed fields, and the start of the tuned ones
    ranges: tuple[tuple[float, float], ...] | None = None  # a law's own parameters: x in [0, 1] over each range

    @classmethod
    def build(cls, names: list[str] | None, base: Params) -> Space:
        """apf: ``names`` of the potential (all by default), in log space; another law: the parameters
        it declares ``ranges`` for (all by default), each range mapped onto [0, 1]."""
        from zswarm.design.guidelines import has_guidelines

        if base.mix.groups:
            raise UsageError("zswarm tune searches the parameters of one law; a mixed swarm (groups) is not tuned: "
                             "tune each law on its own")
        if not has_guidelines(base.law.law):
            return cls._of_law(names, base)
        names = list(TUNABLE) if names is None else names
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

    @classmethod
    def _of_law(cls, names: list[str] | None, base: Params) -> Space:
        from zswarm.laws.registry import resolve

        ranges = resolve(base.law.law)[0].ranges
        if not ranges:
            raise UsageError(f"law {base.law.law} declares no ranges for its parameters, so there is nothing to tune")
        names = list(ranges) if names is None else [n.removeprefix("law.") for n in names]
        unknown = [n for n in names if n not in ranges]
        if unknown or not names or len(set(names)) != len(names):
            raise UsageError(f"cannot tune {', '.join(unknown) or 'that'}: law {base.law.law} declares ranges for "
                             f"{', '.join(ranges)} (--tune takes distinct names among them)")
        return cls(tuple(names), base, tuple(tuple(map(float, ranges[n])) for n in names))

    @property
    def start(self) -> np.ndarray:
        if self.ranges is not None:
            from zswarm.laws.contract import law_params
            from zswarm.laws.registry import resolve

            now = law_params(resolve(self.base.law.law)[0], dict(self.base.law.settings))
            return np.array([min(max((getattr(now, n) - lo) / (hi - lo), 0.0), 1.0)
                             for n, (lo, hi) in zip(self.names, self.ranges)])
        flat = self.base.flat()
        return np.log([float(flat[n]) for n in self.names])

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.ranges is not None:
            return np.zeros(len(self.names)), np.ones(len(self.names))
        return self.start - SPAN, self.start + SPAN

    def values(self, x: np.ndarray) -> dict[str, float]:
        if self.ranges is not None:
            return {n: float(lo + v * (hi - lo)) for n, v, (lo, hi) in zip(self.names, x, self.ranges)}
        return {n: float(math.exp(v)) for n, v in zip(self.names, x)}

    def params(self, x: np.ndarray) -> Params:
        if self.ranges is not None:
            return self.base.with_values({f"law.{n}": v for n, v in self.values(x).items()})
        return self.base.with_values(self.values(x))

