"""The safety filter of one agent in plain floats: :func:`zswarm.control.safety.rows` and
:func:`~zswarm.control.safety.apply` (with inertia, :func:`~zswarm.control.safety.apply_inertia`) for a
batch of one, where numpy's per-call cost would be most of the work (:meth:`zswarm.control.step.ControlStep.one`).
``tests/test_control_step.py`` holds it to the batched form."""

from __future__ import annotations

import math
from itertools import combinations
from typing import NamedTuple, Sequence

import numpy as np

from zswarm.control import safety as sf


class Acted(NamedTuple):
    """What the filter did to one agent's command."""

    acted: bool
    stalled: bool
    braked: bool

    @property
    def flag(self) -> int:
        """Its flag of ``messages.SAFETY_FLAGS``, as :meth:`Filtered.flags`."""
        return 3 if self.braked else 2 if self.stalled else int(self.acted)


def filter_floats(safety: sf.Safety, point: tuple[float, ...], velocity: tuple[float, ...], accel: float,
                  u_hat: tuple[float, ...], neighbours: Sequence[tuple], obstacles: Sequence[tuple[float, ...]],
                  look: float = 0.0, brake: bool = False) -> tuple[tuple[float, ...], Acted | None]:
    """:func:`zswarm.control.safety.apply` of :func:`~zswarm.control.safety.rows` for one agent at ``point``
    (``look`` ahead of its axle; its ``velocity`` and acceleration bound ``accel``, inf for a body that stops
    at once) with ``neighbours`` as (believed point, age, look-ahead[, velocity, accel]) and ``obstacles``
    as (centre..., radius); ``brake``: its world is late. The same rows and the same exact enumeration, in
    floats; most ticks no row binds and the command passes at the cost of a few float operations. Returns
    the command and what the filter did (None: nothing)."""
    T, v, dims, hair = safety.period, safety.v_max, len(point), 1.0 + sf.HAIR
    rate = safety.kappa / T
    own = math.isfinite(accel) and accel > 0
    inert = own or any(len(x) > 3 and math.isfinite(x[4]) for x in neighbours)  # (S4)'s rows, as the batch's
    speed2 = sum(c * c for c in velocity) if own else 0.0
    stop = speed2 / (2.0 * accel) if own else 0.0
    far = 2.0 * v * math.sqrt(2.0) / rate  # a gap this wide gives b >= |a| v_max for every row: none binds
    pairs, least = [], math.inf
    for q, age, theirs, *motion in neighbours:
        d = math.dist(point, q)
        widen = (look + theirs) * hair + stop
        if motion and math.isfinite(motion[1]) and motion[1] > 0:  # its braking distance
            s_j = min(math.sqrt(sum(c * c for c in motion[0])) + motion[1] * age, v)
            widen += s_j * s_j / (2.0 * motion[1])
        gap = d - (safety.distance + v * age) - widen  # the order of rows()' arithmetic
        if not own and gap >= far and age <= safety.max_age - widen / v:
            continue  # most neighbours, most ticks: nothing more is computed
        b = 0.5 * rate * max(gap, 0.0)
        least = min(least, b)
        pairs.append((q, age, d, widen, b))
    obstacle_rows = []
    for o in obstacles:
        d = math.dist(point, o[:dims])
        b = rate * max(d - o[dims] - safety.clearance - look * hair - stop, 0.0)
        least = min(least, b)
        if inert or b < v:
            obstacle_rows.append((tuple((point[k] - o[k]) / d for k in range(dims)) if d > 0 else (0.0,) * dims, b))
    gain, extra, held, reach, wanted = (0.0,) * dims, 0.0, (0.0,) * dims, math.inf, u_hat
    if own:
        step2 = (T * accel) ** 2
        rho2 = min(step2, 2.0 * accel * T * least + 2.0 * speed2) if math.isfinite(least) else step2
        gain, extra = tuple(c / (accel * T) for c in velocity), (speed2 - 0.5 * rho2) / (accel * T)
        speed = math.sqrt(speed2)
        slow = min(speed, T * accel) / speed if speed > 0 else 1.0
        held, reach = tuple(c * (1.0 - slow) for c in velocity), math.sqrt(rho2)
        gap = [u_hat[k] - velocity[k] for k in range(dims)]
        norm = math.sqrt(sum(c * c for c in gap))
        scale = min(1.0, reach / norm) if norm > 0 else 1.0
        wanted = tuple(velocity[k] + gap[k] * scale for k in range(dims))
    rows_: list[tuple[tuple[float, ...], float]] = []
    stale = brake
    for q, age, d, widen, b in pairs:
        spread = min(v * age / d, 1.0) if d > 0 else 1.0
        cos = math.sqrt(1.0 - spread * spread)
        unit = [(point[k] - q[k]) / d for k in range(dims)] if d > 0 else [0.0] * dims
        mine = [(tuple(-unit[k] + cos * gain[k] for k in range(dims)), cos * (b + extra))]
        if spread > 0:
            mine += [(tuple(-(cos * unit[k] - spread * e[k]) + gain[k] for k in range(dims)), b + extra)
                     for e in _tangents(unit)]
        if inert:  # every row kept; any of the pair's may bind
            rows_ += mine
            could = any(bound < v * math.sqrt(sum(c * c for c in a)) for a, bound in mine)
        else:
            could = cos * b < v * math.sqrt(1.0 + (dims - 2) * spread * spread)
            rows_ += mine if could else []
        stale |= could and (age > safety.max_age - widen / v or v * age >= d)
    rows_ += [(tuple(-n[k] + gain[k] for k in range(dims)), b + extra) for n, b in obstacle_rows]
    shifted = [(a, b - sum(a[k] * held[k] for k in range(dims))) for a, b in rows_]  # about braking
    stale |= any(b < -sf.TOL for _, b in shifted)
    speed = math.sqrt(sum(c * c for c in wanted))
    w = tuple(wanted[k] - held[k] for k in range(dims))
    u = held if stale else wanted
    if not stale and any(sum(a[k] * w[k] for k in range(dims)) - b > sf.TOL for a, b in shifted):
        binding = [(a, max(b, 0.0)) for a, b in shifted]
        size = math.sqrt(sum(c * c for c in w))
        w = _project(w, [r for r in binding if r[1] < size * math.sqrt(sum(c * c for c in r[0])) + sf.TOL])
        if not own:  # take_detour, in floats
            w = _detour(wanted, w, binding, speed)
        u = tuple(held[k] + w[k] for k in range(dims))
    if inert and not stale and ((math.isfinite(reach) and math.dist(u, velocity) > reach)
                                or math.sqrt(sum(c * c for c in u)) > v):
        u = tuple(sf._within(np.array([held]), np.array([u]), np.array([velocity], dtype=float),
                             np.array([reach]), v)[0].tolist())
    moved = math.sqrt(sum((u[k] - wanted[k]) ** 2 for k in range(dims))) > 1e-9 * max(speed, 1.0)
    if not (moved or stale):
        return wanted, None
    return u, Acted(moved, moved and math.sqrt(sum(c * c for c in u)) < sf.STALL_SHARE * speed, stale)


def _detour(u_hat: tuple[float, ...], u: tuple[float, ...], rows_: list, speed: float) -> tuple[float, ...]:
    """:func:`zswarm.control.safety.take_detour` for one agent, in floats."""
    size = math.sqrt(sum(c * c for c in u))
    if size >= sf.STALL_SHARE * speed:
        return u
    cos, sin = math.cos(sf.DETOUR), math.sin(sf.DETOUR)
    turned = (cos * u_hat[0] + sin * u_hat[1], -sin * u_hat[0] + cos * u_hat[1], *u_hat[2:])
    fits = all(sum(a[k] * turned[k] for k in range(len(u))) - b <= sf.TOL for a, b in rows_)
    alt = turned if fits else _project(turned, rows_)
    return alt if math.sqrt(sum(x * x for x in alt)) > size + 1e-9 * speed else u


def _tangents(unit: list[float]) -> list[tuple[float, ...]]:
    """The E_ij of :func:`zswarm.control.safety.rows` for one direction, in floats (the same vectors)."""
    if len(unit) == 2:
        return [(-unit[1], unit[0]), (unit[1], -unit[0])]
    k = min(range(3), key=lambda i: abs(unit[i]))
    axis = [1.0 if i == k else 0.0 for i in range(3)]
    t1 = _cross(unit, axis)
    n1 = math.sqrt(sum(c * c for c in t1))
    t1 = [c / n1 for c in t1] if n1 > 0 else [0.0, 0.0, 0.0]
    t2 = _cross(unit, t1)
    return [tuple(s1 * t1[i] + s2 * t2[i] for i in range(3)) for s1, s2 in ((1, 1), (1, -1), (-1, 1), (-1, -1))]


def _cross(x: list[float], y: list[float]) -> list[float]:
    return [x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]]


def _project(u_hat: tuple[float, ...], rows_: list[tuple[tuple[float, ...], float]]) -> tuple[float, ...]:
    """The exact projection of :func:`zswarm.control.safety.project` for one agent in floats: onto every
    active set of at most D linearly independent rows, closest first; the first that satisfies every
    row is the optimum (0 always does)."""
    dims = len(u_hat)
    cands = []
    for size in range(1, min(dims, len(rows_)) + 1):
        for chosen in combinations(rows_, size):
            u = _affine_projection(u_hat, chosen)
            if u is not None:
                cands.append((sum((u[k] - u_hat[k]) ** 2 for k in range(dims)), u))
    cands.sort(key=lambda c: c[0])
    for _, u in cands:
        if all(sum(a[k] * u[k] for k in range(dims)) - b <= sf.TOL for a, b in rows_):
            return u
    return (0.0,) * dims


def _affine_projection(u_hat: tuple[float, ...], chosen) -> tuple[float, ...] | None:
    """u^ - A^T (A A^T)^-1 (A u^ - b) for 1, 2 or 3 rows (Cramer's rule); None if they are dependent."""
    dims = len(u_hat)
    a = [r[0] for r in chosen]
    rhs = [sum(r[0][k] * u_hat[k] for k in range(dims)) - r[1] for r in chosen]
    g = [[sum(x[k] * y[k] for k in range(dims)) for y in a] for x in a]
    n = len(chosen)
    det = g[0][0] if n == 1 else g[0][0] * g[1][1] - g[0][1] * g[1][0] if n == 2 else _det3(g)
    if abs(det) <= 1e-12:
        return None
    if n == 1:
        lam = [rhs[0] / det]
    elif n == 2:
        lam = [(rhs[0] * g[1][1] - g[0][1] * rhs[1]) / det, (g[0][0] * rhs[1] - rhs[0] * g[1][0]) / det]
    else:
        lam = [_det3([[rhs[i] if j == c else g[i][j] for j in range(3)] for i in range(3)]) / det for c in range(3)]
    return tuple(u_hat[k] - sum(lam[i] * a[i][k] for i in range(n)) for k in range(dims))


def _det3(m: list[list[float]]) -> float:
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))
