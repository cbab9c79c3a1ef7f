"""The control law of one agent in plain floats: P' = sat(-grad U_i) (eq 5 with the speed limit).

The same arithmetic as :func:`zswarm.model.potentials.field` for a single agent, term by term and in
the same order, written for the handful of obstacles and neighbours one agent senses. At that size
numpy's per-call overhead is most of the cost (about 0.23 ms a step with arrays, a tenth of that
here), and an agent process steps 20 times a second. ``tests/test_agent_law.py`` checks it against
the vectorized law on random configurations; the lockstep test checks whole runs against the
reference simulator.

- goal (eqs 7-8): U^g = c_g (1 - e^{-|psi_g|^2/l_g^2}), F^g = -2 c_g/l_g^2 e^{...} psi_g;
- obstacles (eqs 9-11, circles through their nearest boundary point): U^o = sum c_o e^{-|psi_o|^2/l_o^2},
  F^o = sum 2/l_o^2 c_o e^{...} psi_o;
- combination: additive (eqs 12-13) F = F^o + F^g; multiplicative (eqs 14-15)
  F = (U^g/c_g) F^o + (1 + U^o/c_g) F^g;
- formation (eqs 26-28): F^f = -sum g(|psi_f|^2) psi_f, g as in :func:`zswarm.model.formation.pair_gain`.
"""

from __future__ import annotations

import math
from typing import Iterable

from zswarm.model.params import PotentialParams
from zswarm.model.potentials import Combination

Point = tuple[float, float]
Circle = tuple[float, float, float]  # centre x, y and radius (0: the paper's point obstacle)


def agent_velocity(x: float, y: float, goal: Point, obstacles: Iterable[Circle], neighbours: Iterable[Point],
                   sensing_radius: float, p: PotentialParams, combination: Combination, formation: bool,
                   v_max: float) -> Point:
    """Commanded velocity of the agent at (x, y) from what it sensed: obstacles whose nearest boundary
    point, and neighbours, within ``sensing_radius`` count (the others are ignored here)."""
    r2_max = sensing_radius * sensing_radius
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
        fx, fy = fox + fgx, foy + fgy
    else:
        a, b = u_g / p.c_g, 1.0 + u_o / p.c_g
        fx, fy = a * fox + b * fgx, a * foy + b * fgy

    if formation:
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

    speed = math.sqrt(fx * fx + fy * fy)
    if speed > v_max:
        s = v_max / speed
        return fx * s, fy * s
    return fx, fy
