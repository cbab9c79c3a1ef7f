"""Reynolds (1987), "Flocks, herds, and schools: a distributed behavioral model", Computer Graphics
21(4):25-34: separation, alignment and cohesion, plus a target term, in the steering form of Reynolds
(1999) and Shiffman's *Nature of Code* (its "Flocking" example's defaults).

Each rule asks for a desired velocity and steers toward it with a bounded force:

    steer(desired) = limit(desired - v_i, F_max)
    separation: desired = v_max unit(mean_{j: 0 < r_ij < R_sep} unit(r_i - r_j) / r_ij)   (none if that is 0)
    alignment:  desired = v_max unit(mean_{j: 0 < r_ij < R} v_j)
    cohesion:   desired = v_max unit(mean_{j: 0 < r_ij < R} r_j - r_i)       (seek the neighbours' centre)
    target:     desired = v_max unit(target - r_i)                           (seek the target)
    a = w_sep sep + w_ali ali + w_coh coh + w_tgt tgt,   v <- limit(v_i + a dt, v_max)

once per frame; here a frame lasts the law's time unit (:mod:`zswarm.laws.scale`), so a control step of
dt adds a dt. Neighbours are those within R = 2 R_sep (Shiffman's 50 px for a 25 px separation) and the
sensing radius. Obstacles, which Reynolds steers around by a rule of their own, are left to the safety
filter here (the law ignores them). Published values: w_sep 1.5, w_ali 1, w_coh 1, R_sep 25 px,
v_max 2 px a frame, F_max 0.03 px a frame^2; the target's weight, w_tgt = 1, is this project's choice
(no standard value exists).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zswarm.laws.contract import Observations, SwarmLaw, masked_sum, norm, param, saturate_2d, unit, unit_2d
from zswarm.laws.scale import Units
from zswarm.paper.potentials import saturate


@dataclass(frozen=True)
class BoidsParams:
    r_sep: float = param(25.0, "length", "separation radius R_sep (the spacing)")
    r_neighbour: float = param(50.0, "length", "alignment and cohesion radius")
    w_sep: float = param(1.5, "none", "separation weight", lo_open=False)
    w_ali: float = param(1.0, "none", "alignment weight", lo_open=False)
    w_coh: float = param(1.0, "none", "cohesion weight", lo_open=False)
    w_tgt: float = param(1.0, "none", "target weight (this project's choice)", lo_open=False)
    f_max: float = param(0.03, "accel", "the largest steering force F_max")
    top_speed: float = param(2.0, "speed", "v_max, px a frame: what the scenario's v_max stands for")


class Boids(SwarmLaw):
    name = "boids"
    reference = "Reynolds (1987), Computer Graphics 21(4):25-34; Shiffman, The Nature of Code, Flocking"
    Params = BoidsParams
    needs = ("neighbour velocities",)
    ranges = {"w_sep": (0.5, 4.0), "w_ali": (0.0, 3.0), "w_coh": (0.0, 3.0), "w_tgt": (0.2, 4.0)}

    def __init__(self, params: BoidsParams, context) -> None:
        super().__init__(params, context)
        self.units = Units.fit(context, params.r_sep, params.top_speed)

    def batch(self, obs: Observations) -> np.ndarray:
        p, law = self.params, self.units.to_law(obs)
        r, v, top = law.position, law.velocity, np.asarray(law.v_max, dtype=float)
        top_b = np.broadcast_to(top, r.shape[:-1])[..., None]

        def steer(desired: np.ndarray) -> np.ndarray:
            return saturate(desired - v, p.f_max)

        away = r[..., None, :] - law.neighbour_position
        dist = norm(away)
        apart = obs.neighbour_mask & (dist > 0.0)  # Reynolds' 0 < d: a boid at its own position is nobody
        near = apart & (dist < p.r_neighbour)
        close = apart & (dist < p.r_sep)
        push = unit(away) / np.where(dist > 0.0, dist, 1.0)[..., None]
        sep = masked_sum(push, close) / np.maximum(close.sum(axis=-1), 1)[..., None]
        count = np.maximum(near.sum(axis=-1), 1)[..., None]
        ali = masked_sum(law.neighbour_velocity, near) / count
        centre = masked_sum(law.neighbour_position, near) / count
        some = near.any(axis=-1)[..., None]
        # separation steers only when the summed push has a length (pushes that cancel ask for nothing)
        a = p.w_sep * np.where(norm(sep)[..., None] > 0.0, steer(top_b * unit(sep)), 0.0)
        a += p.w_ali * np.where(some, steer(top_b * unit(ali)), 0.0)
        a += p.w_coh * np.where(some, steer(top_b * unit(centre - r)), 0.0)
        a += p.w_tgt * steer(top_b * unit(law.target - r))
        return saturate(v + a * law.dt, top) * self.units.speed

    def floats(self, position, velocity, target, obstacles, neighbours, v_max: float, dt: float) -> tuple[float, float]:
        """:meth:`batch` for one 2-D agent in plain floats (an agent process's tick)."""
        p, lam, sig = self.params, self.units.length, self.units.speed
        x, y, vx, vy = position[0] / lam, position[1] / lam, velocity[0] / sig, velocity[1] / sig
        top, f_max = v_max / sig, p.f_max
        sx = sy = ax_ = ay_ = cx = cy = 0.0
        close = near = 0
        for (nx, ny), (nvx, nvy), _ in neighbours:
            dx, dy = x - nx / lam, y - ny / lam
            d = math.sqrt(dx * dx + dy * dy)
            if d <= 0.0:
                continue
            if d < p.r_neighbour:
                near += 1
                ax_ += nvx / sig
                ay_ += nvy / sig
                cx += nx / lam
                cy += ny / lam
            if d < p.r_sep:
                close += 1
                ux, uy = dx / d, dy / d
                sx += ux / d
                sy += uy / d

        def steer(dx: float, dy: float) -> tuple[float, float]:
            ux, uy = unit_2d(dx, dy)
            return saturate_2d(top * ux - vx, top * uy - vy, f_max)

        k = max(close, 1)
        sx, sy = sx / k, sy / k
        a_x = a_y = 0.0
        if math.sqrt(sx * sx + sy * sy) > 0.0:
            fx, fy = steer(sx, sy)
            a_x, a_y = p.w_sep * fx, p.w_sep * fy
        if near:
            k = near
            fx, fy = steer(ax_ / k, ay_ / k)
            a_x, a_y = a_x + p.w_ali * fx, a_y + p.w_ali * fy
            fx, fy = steer(cx / k - x, cy / k - y)
            a_x, a_y = a_x + p.w_coh * fx, a_y + p.w_coh * fy
        fx, fy = steer(target[0] / lam - x, target[1] / lam - y)
        a_x, a_y = a_x + p.w_tgt * fx, a_y + p.w_tgt * fy
        tau = lam / sig
        wx, wy = saturate_2d(vx + a_x * (dt / tau), vy + a_y * (dt / tau), top)
        return wx * sig, wy * sig
