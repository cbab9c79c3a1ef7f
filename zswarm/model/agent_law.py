"""The control law of one agent in plain floats: P' = sat(-grad U_i) (eq 5 with the speed limit).

A thin specialisation of the one law, :func:`zswarm.model.law.field`, for one 2-D agent: the same
arithmetic term by term and in the same order, written for the handful of obstacles and neighbours
one agent senses. At that size numpy's per-call overhead is most of the cost (about 0.23 ms a step
with arrays, a tenth of that here; ``docs/benchmarks.md``), and an agent process steps 20 times a
second. ``tests/test_one_law.py`` holds it equal to the law (1e-12) on random states for every
interaction and combination, and its point-body step to :func:`zswarm.model.body.step`; the lockstep
test checks whole runs against the reference simulator.

- goal (eqs 7-8): U^g = c_g (1 - e^{-|psi_g|^2/l_g^2}), F^g = -2 c_g/l_g^2 e^{...} psi_g;
- obstacles (eqs 9-11, circles through their nearest boundary point): U^o = sum c_o e^{-|psi_o|^2/l_o^2},
  F^o = sum 2/l_o^2 c_o e^{...} psi_o;
- combination: additive (eqs 12-13) F = F^o + F^g; multiplicative (eqs 14-15)
  F = (U^g/c_g) F^o + (1 + U^o/c_g) F^g;
- formation (eqs 26-28): F^f = -sum g(|psi_f|^2) psi_f, g as in :func:`zswarm.model.formation.pair_gain`;
  or, with ``law``, the interaction of :func:`zswarm.model.neighbour_law.neighbour_force` (its goal gate
  weighs the goal term of the combination);
- swirl (:func:`zswarm.model.neighbour_law.swirl_force`): kappa (-F^g_y, F^g_x) within rho of the goal.
"""

from __future__ import annotations

import math
from typing import Iterable

from zswarm.model.neighbour_law import (
    AHEAD_COS,
    AHEAD_FULL,
    CUTOFF_INNER,
    NeighbourLaw,
)
from zswarm.model.params import PotentialParams
from zswarm.model.potentials import Combination

Point = tuple[float, float]
Triple = tuple[float, float, float | None]
Circle = tuple[float, float, float]  # centre x, y and radius (0: the paper's point obstacle)


def agent_velocity(x: float, y: float, goal: Point, obstacles: Iterable[Circle], neighbours: Iterable[Point],
                   sensing_radius: float, p: PotentialParams, combination: Combination, formation: bool,
                   v_max: float, law: NeighbourLaw | None = None) -> Point:
    """Commanded velocity of the agent at (x, y) from what it sensed: obstacles whose nearest boundary
    point, and neighbours, within ``sensing_radius`` count (the others are ignored here). ``law``: an
    interaction other than the paper's."""
    r2_max = sensing_radius * sensing_radius
    goal_weight, variant = 1.0, None
    if formation and law is not None and not law.interaction.is_paper:
        variant, goal_weight = _neighbour_force(x, y, goal, neighbours, r2_max, p, law)
    gx, gy = x - goal[0], y - goal[1]
    lg2 = p.l_g**2
    e = math.exp(-(gx * gx + gy * gy) / lg2)
    u_g = p.c_g * (1.0 - e)
    k = -2.0 * p.c_g / lg2 * e
    fgx, fgy = k * gx, k * gy

    lo2 = p.l_o**2
    u_o = fox = foy = 0.0
    for cx, cy, rho in obstacles:
        dx, dy = x - cx, y - cy
        dist = math.sqrt(dx * dx + dy * dy)
        scale = 1.0 - rho / dist if dist > 0.0 else 0.0
        px, py = dx * scale, dy * scale
        d2 = px * px + py * py
        if d2 > r2_max:
            continue
        e = p.c_o * math.exp(-d2 / lo2)
        u_o += e
        k = 2.0 / lo2 * e
        fox += k * px
        foy += k * py

    if combination == "additive":
        fx, fy = fox + goal_weight * fgx, foy + goal_weight * fgy
    else:
        a, b = u_g / p.c_g, 1.0 + u_o / p.c_g
        fx, fy = a * fox + goal_weight * (b * fgx), a * foy + goal_weight * (b * fgy)

    if variant is not None:
        fx, fy = fx + variant[0], fy + variant[1]
    elif formation:
        lr2, la2 = p.l_r**2, p.l_a**2
        ffx = ffy = 0.0
        for nx, ny in neighbours:
            px, py = x - nx, y - ny
            r2 = px * px + py * py
            if r2 > r2_max:
                continue
            g = (-2.0 * p.c_r / lr2 * math.exp(-r2 / lr2) + 2.0 * p.c_a / la2 * math.exp(-r2 / la2)
                 + 2.0 * p.c_a_prime)
            ffx += -g * px
            ffy += -g * py
        fx, fy = fx + ffx, fy + ffy
    if law is not None and law.interaction.swirl and gx * gx + gy * gy < law.swirl_radius * law.swirl_radius:
        fx, fy = fx + law.swirl * -fgy, fy + law.swirl * fgx

    speed = math.sqrt(fx * fx + fy * fy)
    if speed > v_max:
        s = v_max / speed
        return fx * s, fy * s
    return fx, fy


def _neighbour_force(x: float, y: float, goal: Point, neighbours: Iterable[Point], r2_max: float,
                     p: PotentialParams, law: NeighbourLaw) -> tuple[Point, float]:
    """:func:`zswarm.model.neighbour_law.neighbour_force` for one agent: its force from the neighbours
    within reach and the weight of its goal term."""
    spec = law.interaction
    sensed = []
    for nx, ny in neighbours:
        px, py = x - nx, y - ny
        r2 = px * px + py * py
        if r2 <= r2_max:
            sensed.append((r2, px, py))
    if spec.nearest:
        sensed.sort(key=lambda s: s[0])  # stable: ties keep the order heard, as the vectorized rank does
        del sensed[law.k_nearest:]
    gx, gy = goal[0] - x, goal[1] - y
    gd = math.sqrt(gx * gx + gy * gy)
    tx, ty = (gx / gd, gy / gd) if gd > 0.0 else (0.0, 0.0)
    lr2, la2 = p.l_r**2, p.l_a**2
    radius = math.sqrt(r2_max)
    rx = ry = ax = ay = wsum = block = 0.0
    for r2, px, py in sensed:
        r = math.sqrt(r2)
        w = 1.0
        if spec.cutoff:
            z = (r / radius - CUTOFF_INNER) / (1.0 - CUTOFF_INNER)
            w = 1.0 if z <= 0.0 else 0.0 if z >= 1.0 else 0.5 * (1.0 + math.cos(math.pi * z))
            if w <= 0.0:
                continue
        g_r = -2.0 * p.c_r / lr2 * math.exp(-r2 / lr2)
        g_a = 2.0 * p.c_a / la2 * math.exp(-r2 / la2) + 2.0 * p.c_a_prime
        rx += -w * g_r * px
        ry += -w * g_r * py
        ax += -w * g_a * px
        ay += -w * g_a * py
        wsum += w
        if spec.gate:
            cos = -(px * tx + py * ty) / (r if r > 0.0 else 1.0)
            near = min(max((law.gate_out - r) / (law.gate_out - law.gate_in), 0.0), 1.0)
            ahead = min(max((cos - AHEAD_COS) / (AHEAD_FULL - AHEAD_COS), 0.0), 1.0)
            block = max(block, near * ahead)
    if spec.mean:
        k = max(wsum, 1.0)
        ax, ay = ax / k, ay / k
    return (rx + ax, ry + ay), 1.0 - block


def point_step(x: float, y: float, z: float | None, v_d: tuple[float, ...], dt: float) -> tuple[Triple, Triple]:
    """The point body's step (:func:`zswarm.model.body.step` for ``point``) in plain floats: P + dt v_d
    and the velocity v_d; z (and the third component) stays None in 2-D."""
    if z is None:
        return (x + dt * v_d[0], y + dt * v_d[1], None), (v_d[0], v_d[1], None)
    return (x + dt * v_d[0], y + dt * v_d[1], z + dt * v_d[2]), (v_d[0], v_d[1], v_d[2])
