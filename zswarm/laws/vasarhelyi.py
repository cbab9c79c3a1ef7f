"""Vásárhelyi et al. (2018), "Optimized flocking of autonomous drones in confined environments",
Science Robotics 3(20):eaat3536: a desired velocity from four terms, as in the authors' simulator
(robotsim: algo_spp_evol.c, interactions.c) and SwarmLab's port.

    v~_i = v_spp + sum_j v_rep_ij + sum_j v_frict_ij + sum_s v_shill_is
    v_i^d = unit(v~_i) min(|v~_i|, v_max)

- self-propulsion toward the target (SwarmLab's goal mode): v_spp = v_flock unit(target - r_i);
- repulsion, a half spring within r0_rep: v_rep = p_rep (r0_rep - r_ij) unit(r_i - r_j);
- alignment with the braking curve: v_frictmax = max(v_frict, D(r_ij - r0_frict, a_frict, p_frict)); where
  |v_ij| > v_frictmax, v_frict = C_frict (|v_ij| - v_frictmax) unit(v_j - v_i);
- obstacles through shill agents at the nearest point of each obstacle's surface, moving away from it
  at v_shill: v_shillmax = D(r_is - r0_shill, a_shill, p_shill); where |v_i - v_s| > v_shillmax,
  v_shill = (|v_i - v_s| - v_shillmax) unit(v_s - v_i);

with the braking curve D(r, a, p) = 0 for r <= 0, r p for 0 < r p < a / p, sqrt(2 a r - a^2 / p^2) beyond.

Where the sources disagree: the alignment's direction is robotsim's unit(v_j - v_i), which shrinks the
velocity difference (SwarmLab's unit(v_i - v_j) anti-aligns); p_rep is the ports' 0.13 1/s (SwarmLab
0.03, too weak to keep agents apart at this spacing); r0_rep is SwarmLab's d_ref = 25 m, the spacing.
The alignment and shill values are the published optimized set; v_flock = 6 and the top speed 7 m/s are
SwarmLab's v_ref and max_v (:mod:`zswarm.laws.scale` maps 25 m to the scenario's spacing and 7 m/s to
its v_max). The law has no attraction term (the paper has none): the target holds the flock together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zswarm.laws.contract import Observations, SwarmLaw, masked_sum, norm, param, saturate_2d, unit, unit_2d
from zswarm.laws.scale import Units
from zswarm.paper.potentials import saturate


@dataclass(frozen=True)
class VasarhelyiParams:
    r0_rep: float = param(25.0, "length", "repulsion range r0_rep (the spacing)")
    p_rep: float = param(0.13, "rate", "repulsion gain p_rep")
    r0_frict: float = param(85.3, "length", "alignment: the stopping-distance offset r0_frict", lo_open=False)
    c_frict: float = param(0.05, "none", "alignment gain C_frict", lo_open=False, hi=1.0)
    v_frict: float = param(0.63, "speed", "alignment: the velocity difference always allowed", lo_open=False)
    p_frict: float = param(3.20, "rate", "alignment: the braking curve's gain p_frict")
    a_frict: float = param(4.16, "accel", "alignment: the braking curve's deceleration a_frict")
    r0_shill: float = param(0.3, "length", "obstacles: the shill's stopping-distance offset", lo_open=False)
    v_shill: float = param(13.6, "speed", "obstacles: the shill agents' speed")
    p_shill: float = param(3.55, "rate", "obstacles: the braking curve's gain p_shill")
    a_shill: float = param(3.02, "accel", "obstacles: the braking curve's deceleration a_shill")
    v_flock: float = param(6.0, "speed", "self-propulsion speed toward the target")
    top_speed: float = param(7.0, "speed", "the speed the scenario's v_max stands for (SwarmLab's max_v)")


def braking(r: np.ndarray, a: float, p: float) -> np.ndarray:
    """D(r, a, p): the largest velocity difference an agent can still brake away over distance r."""
    rp = r * p
    far = np.sqrt(np.maximum(2.0 * a * r - a * a / (p * p), 0.0))
    return np.where(r <= 0.0, 0.0, np.where(rp < a / p, rp, far))


def braking_float(r: float, a: float, p: float) -> float:
    """:func:`braking` of one distance."""
    if r <= 0.0:
        return 0.0
    rp = r * p
    return rp if rp < a / p else math.sqrt(max(2.0 * a * r - a * a / (p * p), 0.0))


class Vasarhelyi(SwarmLaw):
    name = "vasarhelyi"
    reference = "Vásárhelyi et al. (2018), Science Robotics 3(20):eaat3536; robotsim, SwarmLab"
    Params = VasarhelyiParams
    needs = ("neighbour velocities", "obstacles")
    ranges = {"p_rep": (0.03, 1.0), "c_frict": (0.0, 0.5), "v_flock": (2.0, 7.0)}

    def __init__(self, params: VasarhelyiParams, context) -> None:
        super().__init__(params, context)
        self.units = Units.fit(context, params.r0_rep, params.top_speed)

    def batch(self, obs: Observations) -> np.ndarray:
        p, law = self.params, self.units.to_law(obs)
        r, v = law.position, law.velocity
        mask = obs.neighbour_mask
        v_new = p.v_flock * unit(law.target - r)
        away = r[..., None, :] - law.neighbour_position  # r_i - r_j
        dist = norm(away)
        rep = (p.p_rep * np.maximum(p.r0_rep - dist, 0.0))[..., None] * unit(away)
        v_new += masked_sum(rep, mask & (dist < p.r0_rep))
        dv = law.neighbour_velocity - v[..., None, :]  # v_j - v_i
        speed_diff = norm(dv)
        allowed = np.maximum(p.v_frict, braking(dist - p.r0_frict, p.a_frict, p.p_frict))
        frict = (p.c_frict * np.maximum(speed_diff - allowed, 0.0))[..., None] * unit(dv)
        v_new += masked_sum(frict, mask)
        out = r[..., None, :] - law.obstacle_centre
        gap = norm(out) - law.obstacle_radius  # to the nearest point of the surface
        v_s = p.v_shill * unit(out)
        ds = v_s - v[..., None, :]
        shill_diff = norm(ds)
        shill = np.maximum(shill_diff - braking(gap - p.r0_shill, p.a_shill, p.p_shill), 0.0)[..., None] * unit(ds)
        v_new += masked_sum(shill, obs.obstacle_mask)
        return saturate(v_new, law.v_max) * self.units.speed

    def floats(self, position, velocity, target, obstacles, neighbours, v_max: float, dt: float) -> tuple[float, float]:
        """:meth:`batch` for one 2-D agent in plain floats (an agent process's tick)."""
        p, lam, sig = self.params, self.units.length, self.units.speed
        x, y, vx, vy = position[0] / lam, position[1] / lam, velocity[0] / sig, velocity[1] / sig
        ux, uy = unit_2d(target[0] / lam - x, target[1] / lam - y)
        wx, wy = p.v_flock * ux, p.v_flock * uy
        rx = ry = fx = fy = 0.0
        for (nx, ny), (nvx, nvy), _ in neighbours:
            ax, ay = x - nx / lam, y - ny / lam  # r_i - r_j
            dist = math.sqrt(ax * ax + ay * ay)
            if dist < p.r0_rep:
                k = p.p_rep * max(p.r0_rep - dist, 0.0)
                ux, uy = unit_2d(ax, ay)
                rx, ry = rx + k * ux, ry + k * uy
            dx, dy = nvx / sig - vx, nvy / sig - vy  # v_j - v_i
            allowed = max(p.v_frict, braking_float(dist - p.r0_frict, p.a_frict, p.p_frict))
            k = p.c_frict * max(math.sqrt(dx * dx + dy * dy) - allowed, 0.0)
            ux, uy = unit_2d(dx, dy)
            fx, fy = fx + k * ux, fy + k * uy
        wx, wy = wx + rx, wy + ry
        wx, wy = wx + fx, wy + fy
        sx = sy = 0.0
        for cx, cy, radius in obstacles:
            ox, oy = x - cx / lam, y - cy / lam
            gap = math.sqrt(ox * ox + oy * oy) - radius / lam
            ux, uy = unit_2d(ox, oy)
            dx, dy = p.v_shill * ux - vx, p.v_shill * uy - vy
            k = max(math.sqrt(dx * dx + dy * dy) - braking_float(gap - p.r0_shill, p.a_shill, p.p_shill), 0.0)
            ux, uy = unit_2d(dx, dy)
            sx, sy = sx + k * ux, sy + k * uy
        wx, wy = saturate_2d(wx + sx, wy + sy, v_max / sig)
        return wx * sig, wy * sig
