"""Small numeric helpers: 1-D roots and maxima for the design checks (no SciPy needed), and the
finiteness check every model input goes through."""

from __future__ import annotations

import math
from typing import Callable, Iterable

import numpy as np

Fn = Callable[[np.ndarray], np.ndarray]


def all_finite(values: Iterable[object]) -> bool:
    """Every value a real, finite number (a TOML file may hold ``nan`` and ``inf``)."""
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def bisect(fn: Fn, a: float, b: float, iters: int = 100) -> float:
    """A root of ``fn`` in [a, b], given that ``fn`` changes sign there."""
    fa = float(fn(np.array(a)))
    for _ in range(iters):
        m = 0.5 * (a + b)
        fm = float(fn(np.array(m)))
        if (fm < 0) == (fa < 0):
            a, fa = m, fm
        else:
            b = m
        if b - a <= 4e-16 * max(1.0, abs(a)):
            break
    return 0.5 * (a + b)


def sign_changes(fn: Fn, grid: np.ndarray) -> list[tuple[float, int]]:
    """Every root of ``fn`` on ``grid``, refined by bisection, with the sign of ``fn`` before it."""
    values = fn(grid)
    sign = np.sign(values)
    out = []
    for i in np.flatnonzero(sign[:-1] * sign[1:] < 0):
        out.append((bisect(fn, float(grid[i]), float(grid[i + 1])), int(sign[i])))
    return out


def maximize(fn: Fn, grid: np.ndarray, iters: int = 200) -> tuple[float, float, int]:
    """(argmax, max, grid index) of ``fn``: the best grid point, refined by golden-section search."""
    values = fn(grid)
    i = int(np.nanargmax(values))
    lo = float(grid[max(i - 1, 0)])
    hi = float(grid[min(i + 1, len(grid) - 1)])
    g = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = hi - g * (hi - lo), lo + g * (hi - lo)
    fc, fd = float(fn(np.array(c))), float(fn(np.array(d)))
    for _ in range(iters):
        if fc > fd:
            hi, d, fd = d, c, fc
            c = hi - g * (hi - lo)
            fc = float(fn(np.array(c)))
        else:
            lo, c, fc = c, d, fd
            d = lo + g * (hi - lo)
            fd = float(fn(np.array(d)))
        if hi - lo < 1e-15 * max(1.0, abs(hi)):
            break
    x = c if fc > fd else d
    best = max(fc, fd)
    if best < values[i]:
        return float(grid[i]), float(values[i]), i
    return x, best, i
