"""The explicit Euler step against the potentials' stiffness: how large a control period dt the law
can be stepped with before a step overlaps a pair or bounces an agent off an obstacle (the time-step
row of the design report, and the dt a scaled scenario is given)."""

from __future__ import annotations

import math
from typing import Any

from zswarm.paper.params import Params


def obstacle_stiffness(params: Params) -> tuple[float | None, float]:
    """(y_v, k): the outermost clearance y_v at which an obstacle's push 2 c_o y/l_o^2 e^{-y^2/l_o^2}
    (eq 11, at most its full strength: the multiplicative factor U^g/c_g is <= 1) commands v_max, and
    the slope k = |d push/dy| there. Farther out the velocity follows the push; nearer, it is v_max."""
    p, v = params.potential, params.swarm.v_max
    push = lambda y: 2.0 * p.c_o * y / p.l_o**2 * math.exp(-y * y / p.l_o**2)  # noqa: E731
    lo, hi = p.l_o / math.sqrt(2.0), 50.0 * p.l_o
    if push(lo) <= v:
        return None, 0.0  # the push never reaches v_max: its slope is at most its peak curvature
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if push(mid) > v else (lo, mid)
    return lo, v * (2.0 * lo / p.l_o**2 - 1.0 / lo)


def time_step(params: Params, dt: float) -> dict[str, Any]:
    """Explicit Euler must not make an overlap or a bounce the guidelines would be blamed for:

    - two agents closing at v_max each cover 2 v_max dt a step: at most the collision distance 2 d^r;
    - an agent at an obstacle: where the push commands v_max its slope is k = v_max (2 y_v/l_o^2 - 1/y_v),
      and a step y <- y - dt k (y - y*) overshoots the rest point y* unless k dt <= 1 (an agent that
      bounces off an obstacle is thrown at its neighbours).
    """
    step, need = 2.0 * params.swarm.v_max * dt, 2.0 * params.swarm.robot_radius
    y_v, k = obstacle_stiffness(params)
    pair_ok, obstacle_ok = step <= need * (1.0 + 1e-9), k * dt <= 1.0
    detail = (f"two agents close at most 2 v_max dt = {step:.3g} a step ({'<=' if pair_ok else '>'} 2 d^r = {need:.3g}); "
              f"an obstacle's push falls off with slope k = {k:.3g}/s where it commands v_max, k dt = {k * dt:.3g} "
              f"({'<=' if obstacle_ok else '>'} 1)"
              + ("" if pair_ok and obstacle_ok else ": the step can overlap a pair or bounce an agent off an "
                 f"obstacle whatever the guidelines say; use dt <= {min(need / (2 * params.swarm.v_max), 1 / k if k else 1):.3g}"))
    return {"holds": pair_ok and obstacle_ok, "dt": dt, "step": step, "collision_distance": need,
            "obstacle_slope": k, "obstacle_clearance_at_v_max": y_v, "k_dt": k * dt,
            "margin": min(need - step, 1.0 - k * dt), "detail": detail}
