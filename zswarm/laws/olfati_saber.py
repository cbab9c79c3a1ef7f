"""Olfati-Saber (2006), "Flocking for multi-agent dynamic systems: algorithms and theory", IEEE TAC
51(3):401-420, Algorithm 3 (alpha-, beta- and gamma-agents), as a velocity command.

The law gives an acceleration u_i (q' = p, p' = u) from three species of agent:

    u_i = u^alpha + u^beta + u^gamma
    u^alpha = c1a sum_j phi_alpha(||q_j - q_i||_s) n_ij + c2a sum_j a_ij (p_j - p_i)          (Alg. 1, eq 23)
    u^beta  = c1b sum_k phi_beta(||qh_k - q_i||_s) nh_ik + c2b sum_k b_ik (ph_k - p_i)        (Alg. 3, eq 59)
    u^gamma = -c1g sigma_1(q_i - q_r) - c2g (p_i - p_r)                                        (Alg. 3)

with the sigma-norm ||z||_s = (sqrt(1 + eps |z|^2) - 1)/eps (eq 8), n_ij = (q_j - q_i)/sqrt(1 + eps
|q_j - q_i|^2) (eq 23), the bump rho_h (eq 10), phi(z) = ((a + b) sigma_1(z + c) + a - b)/2 with
c = |a - b|/sqrt(4ab) and sigma_1(z) = z/sqrt(1 + z^2) (eq 15), phi_alpha(z) = rho_h(z/r_a) phi(z - d_a)
(eq 16), a_ij = rho_h(||q_j - q_i||_s / r_a) (eq 11), r_a = ||r||_s, d_a = ||d||_s;
phi_beta(z) = rho_hb(z/d_b) (sigma_1(z - d_b) - 1), b_ik = rho_hb(||qh_k - q_i||_s / d_b), d_b = ||d'||_s.
Each obstacle k (a disc, a ball, radius R_k about y_k) is seen through its beta-agent, the nearest point of
its surface with the tangential part of the agent's velocity (eq 55): mu = R_k/|q_i - y_k|,
a_k = (q_i - y_k)/|q_i - y_k|, qh = mu q_i + (1 - mu) y_k, ph = mu (I - a_k a_k^T) p_i; only those
within r' = 1.2 d' count. The gamma-agent is the target as sensed: q_r its position, p_r its velocity
estimated from the last two positions sensed (the law's per-agent state: that position and whether it is
set). The vector sigma_1 in u^gamma bounds the pull (as the TUHH MAS library implements Alg. 3).

The acceleration becomes a velocity command as SwarmLab's port does and LAWS-NOTES recommends:
v = sat_vmax(p_i + u dt), p_i the agent's measured velocity (no wind-up when the safety filter holds it).

Published values (paper, Section VIII): d = 7, r = 1.2 d, d' = 0.6 d, r' = 1.2 d', eps = 0.1, a = b = 5,
h = 0.2 (phi_alpha, a_ij), h = 0.9 (phi_beta). The paper orders its gains c1a < c1g < c1b and takes
c2 = 2 sqrt(c1); the values here are the TUHH port's (c1a, c1b, c1g) = (1, 4.5, 1.2). The paper gives no
speed; its top speed is taken as SwarmLab's ratio of top speed to spacing (7 m/s at 25 m) times d:
1.96 (:mod:`zswarm.laws.scale`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from zswarm.laws.contract import Observations, SwarmLaw, masked_sum, norm, param, saturate_2d
from zswarm.laws.scale import Units
from zswarm.paper.potentials import saturate


@dataclass(frozen=True)
class OlfatiSaberParams:
    d: float = param(7.0, "length", "desired spacing d of the alpha-lattice")
    kappa: float = param(1.2, "none", "interaction range r = kappa d", lo=1.0)
    d_obstacle: float = param(0.6, "none", "beta-agents repel within d' = d_obstacle d")
    eps: float = param(0.1, "1/length^2", "epsilon of the sigma-norm")
    a: float = param(5.0, "accel", "phi's attraction plateau a")
    b: float = param(5.0, "accel", "phi's repulsion plateau b (a <= b)")
    h_alpha: float = param(0.2, "none", "bump h of phi_alpha and a_ij", hi=1.0)
    h_beta: float = param(0.9, "none", "bump h of phi_beta and b_ik", hi=1.0)
    c1_alpha: float = param(1.0, "none", "gain of the alpha gradient term")
    c1_beta: float = param(4.5, "none", "gain of the beta gradient term")
    c1_gamma: float = param(1.2, "none", "gain of the gamma (target) position term")
    c2_alpha: float = param(2.0, "rate", "gain of velocity consensus (2 sqrt(c1_alpha))")
    c2_beta: float = param(2.0 * math.sqrt(4.5), "rate", "gain of the beta velocity term (2 sqrt(c1_beta))")
    c2_gamma: float = param(2.0 * math.sqrt(1.2), "rate", "gain of the gamma velocity term (2 sqrt(c1_gamma))")
    top_speed: float = param(1.96, "speed", "the speed the scenario's v_max stands for (see the module doc)")


def sigma_norm(z: np.ndarray, eps: float) -> np.ndarray:
    """||z||_s = (sqrt(1 + eps |z|^2) - 1) / eps over the last axis (eq 8)."""
    return (np.sqrt(1.0 + eps * np.einsum("...k,...k->...", z, z)) - 1.0) / eps


def sigma_grad(z: np.ndarray, eps: float) -> np.ndarray:
    """sigma_eps(z) = z / sqrt(1 + eps |z|^2): the gradient of the sigma-norm (eq 9)."""
    return z / np.sqrt(1.0 + eps * np.einsum("...k,...k->...", z, z))[..., None]


def sigma_1(z: np.ndarray) -> np.ndarray:
    """z / sqrt(1 + z^2), elementwise."""
    return z / np.sqrt(1.0 + z * z)


def bump(z: np.ndarray, h: float) -> np.ndarray:
    """rho_h(z): 1 on [0, h), a half cosine down to 0 on [h, 1], 0 beyond (eq 10)."""
    mid = 0.5 * (1.0 + np.cos(np.pi * (np.clip(z, h, 1.0) - h) / (1.0 - h)))
    return np.where(z < h, 1.0, np.where(z <= 1.0, mid, 0.0))


class OlfatiSaber(SwarmLaw):
    name = "olfati-saber"
    reference = "Olfati-Saber (2006), IEEE TAC 51(3):401-420, Algorithms 1-3"
    Params = OlfatiSaberParams
    needs = ("neighbour velocities", "obstacles", "state")
    ranges = {"c1_alpha": (0.2, 5.0), "c1_beta": (0.5, 20.0), "c1_gamma": (0.2, 6.0)}

    def __init__(self, params: OlfatiSaberParams, context) -> None:
        super().__init__(params, context)
        self.units = Units.fit(context, params.d, params.top_speed)
        self.state_size = context.dims + 1  # the target position sensed last, and 1 once it is set

    def batch(self, obs: Observations) -> tuple[np.ndarray, np.ndarray]:
        p, law = self.params, self.units.to_law(obs)
        q, v, dt = law.position, law.velocity, law.dt
        eps = p.eps
        r_a, d_a = float(sigma_norm(np.array([p.kappa * p.d]), eps)), float(sigma_norm(np.array([p.d]), eps))
        # alpha: neighbours (eqs 23, 16, 11)
        z = law.neighbour_position - q[..., None, :]
        s = sigma_norm(z, eps)
        rho = bump(s / r_a, p.h_alpha)
        c = abs(p.a - p.b) / math.sqrt(4.0 * p.a * p.b)
        phi = 0.5 * ((p.a + p.b) * sigma_1(s - d_a + c) + (p.a - p.b))
        mask = obs.neighbour_mask
        u = p.c1_alpha * masked_sum((rho * phi)[..., None] * sigma_grad(z, eps), mask)
        u += p.c2_alpha * masked_sum(rho[..., None] * (law.neighbour_velocity - v[..., None, :]), mask)
        # beta: each obstacle's nearest surface point with the tangential velocity (eq 55, eq 59)
        off = q[..., None, :] - law.obstacle_centre
        dist = norm(off)
        safe = np.where(dist > 0.0, dist, 1.0)
        mu = law.obstacle_radius / safe
        a_k = off / safe[..., None]
        q_hat = mu[..., None] * q[..., None, :] + (1.0 - mu)[..., None] * law.obstacle_centre
        v_tan = v[..., None, :] - np.einsum("...mk,...k->...m", a_k, v)[..., None] * a_k
        p_hat = mu[..., None] * v_tan
        zb = q_hat - q[..., None, :]
        d_b = float(sigma_norm(np.array([p.d_obstacle * p.d]), eps))
        sb = sigma_norm(zb, eps)
        rho_b = bump(sb / d_b, p.h_beta)
        within = obs.obstacle_mask & (norm(zb) < 1.2 * p.d_obstacle * p.d) & (dist > 0.0)
        u += p.c1_beta * masked_sum((rho_b * (sigma_1(sb - d_b) - 1.0))[..., None] * sigma_grad(zb, eps), within)
        u += p.c2_beta * masked_sum(rho_b[..., None] * (p_hat - v[..., None, :]), within)
        # gamma: the target, its velocity from the last two sensings (the state)
        last, known = law_state(obs, self.units)
        p_r = np.where(known[..., None], (law.target - last) / dt, 0.0)
        u += -p.c1_gamma * vector_sigma_1(q - law.target) - p.c2_gamma * (v - p_r)
        command = saturate(v + u * dt, law.v_max) * self.units.speed
        state = np.concatenate([obs.target, np.ones(obs.lead + (1,))], axis=-1)
        return command, state


    def floats(self, position, velocity, target, obstacles, neighbours, v_max: float, dt: float,
               state: tuple[float, ...]) -> tuple[tuple[float, float], tuple[float, ...]]:
        """:meth:`batch` for one 2-D agent in plain floats (an agent process's tick): (velocity, state)."""
        p, lam, sig = self.params, self.units.length, self.units.speed
        eps, tau = p.eps, lam / sig
        x, y, vx, vy, h = position[0] / lam, position[1] / lam, velocity[0] / sig, velocity[1] / sig, dt / tau

        def s_norm(zz: float) -> float:  # of a vector whose squared length is zz
            return (math.sqrt(1.0 + eps * zz) - 1.0) / eps

        def bump_f(z: float, h_: float) -> float:
            if z < h_:
                return 1.0
            return 0.5 * (1.0 + math.cos(math.pi * (min(z, 1.0) - h_) / (1.0 - h_))) if z <= 1.0 else 0.0

        r_a, d_a = s_norm((p.kappa * p.d) ** 2), s_norm(p.d * p.d)
        c = abs(p.a - p.b) / math.sqrt(4.0 * p.a * p.b)
        gx = gy = cx = cy = 0.0
        for (nx, ny), (nvx, nvy), _ in neighbours:
            zx, zy = nx / lam - x, ny / lam - y
            zz = zx * zx + zy * zy
            sz = s_norm(zz)
            rho = bump_f(sz / r_a, p.h_alpha)
            w = sz - d_a + c
            phi = 0.5 * ((p.a + p.b) * (w / math.sqrt(1.0 + w * w)) + (p.a - p.b))
            k = math.sqrt(1.0 + eps * zz)
            gx, gy = gx + rho * phi * (zx / k), gy + rho * phi * (zy / k)
            cx, cy = cx + rho * (nvx / sig - vx), cy + rho * (nvy / sig - vy)
        ux, uy = p.c1_alpha * gx, p.c1_alpha * gy
        ux, uy = ux + p.c2_alpha * cx, uy + p.c2_alpha * cy
        d_b = s_norm((p.d_obstacle * p.d) ** 2)
        gx = gy = cx = cy = 0.0
        for ox, oy, radius in obstacles:
            ox, oy = ox / lam, oy / lam
            fx, fy = x - ox, y - oy
            dist = math.sqrt(fx * fx + fy * fy)
            safe = dist if dist > 0.0 else 1.0
            mu = (radius / lam) / safe
            ax, ay = fx / safe, fy / safe
            zx, zy = (mu * x + (1.0 - mu) * ox) - x, (mu * y + (1.0 - mu) * oy) - y
            zz = zx * zx + zy * zy
            if not (math.sqrt(zz) < 1.2 * p.d_obstacle * p.d and dist > 0.0):
                continue
            along = ax * vx + ay * vy
            px_, py_ = mu * (vx - along * ax), mu * (vy - along * ay)
            sb = s_norm(zz)
            rho = bump_f(sb / d_b, p.h_beta)
            w = sb - d_b
            k = math.sqrt(1.0 + eps * zz)
            coef = rho * (w / math.sqrt(1.0 + w * w) - 1.0)
            gx, gy = gx + coef * (zx / k), gy + coef * (zy / k)
            cx, cy = cx + rho * (px_ - vx), cy + rho * (py_ - vy)
        ux, uy = ux + p.c1_beta * gx, uy + p.c1_beta * gy
        ux, uy = ux + p.c2_beta * cx, uy + p.c2_beta * cy
        tx, ty = target[0] / lam, target[1] / lam
        prx = pry = 0.0
        if state[2] > 0.5:
            prx, pry = (tx - state[0] / lam) / h, (ty - state[1] / lam) / h
        ex, ey = x - tx, y - ty
        k = math.sqrt(1.0 + (ex * ex + ey * ey))
        ux, uy = ux + (-p.c1_gamma * (ex / k) - p.c2_gamma * (vx - prx)), uy + (-p.c1_gamma * (ey / k) - p.c2_gamma * (vy - pry))
        wx, wy = saturate_2d(vx + ux * h, vy + uy * h, v_max / sig)
        return (wx * sig, wy * sig), (float(target[0]), float(target[1]), 1.0)


def vector_sigma_1(z: np.ndarray) -> np.ndarray:
    """z / sqrt(1 + |z|^2): sigma_1 on a vector (bounded by 1)."""
    return z / np.sqrt(1.0 + np.einsum("...k,...k->...", z, z))[..., None]


def law_state(obs: Observations, units: Units) -> tuple[np.ndarray, np.ndarray]:
    """The target sensed at the last step (in the law's units) and whether there was one."""
    d = obs.dims
    return obs.state[..., :d] / units.length, obs.state[..., d] > 0.5
