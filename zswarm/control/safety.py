"""The safety filter: the command closest to the law's that keeps every agent apart, on data of any age.

Between the law (:mod:`zswarm.paper.field`) and the body, agent i replaces its command u^ by

    u_i = argmin |u - u^|^2   subject to   a_r . u <= b_r  for every row r of agent i          (S1)

one row per sensed neighbour j and per sensed obstacle (a discrete-time barrier, derived in
``docs/safety.md``; the same rows in 2-D and 3-D):

    neighbour j:  -n_ij . u <= c_j b_ij   and   -(c_j n_ij - s_j e) . u <= b_ij  for each e in E_ij,
                  b_ij = (kappa / 2T) max(0, |psi_ij| - D'_j),   D'_j = D_s + v tau_j,
                  s_j = sin theta_j = v tau_j / |psi_ij|,  c_j = cos theta_j                             (S2)
    obstacle o:   -n_io . u <= (kappa / T)  max(0, |P_i - C_o| - rho_o - D_o)                     (S3)

with psi_ij = P_i - P_j as agent i believes it (P_j heard tau_j seconds ago), n = psi/|psi|, D_s = 2 d^r
(two bodies touching: the collision distance the metrics count), D_o = d^r, v = v_max, T the control
period and kappa in (0, 1] the share of the gap the pair may close in one period. Each agent takes half
of a neighbour's gap (the other agent takes the other half); an obstacle does not move, so the agent
takes all of it. The distance to a point is convex, so one period of motion can only leave a pair
farther apart than its first-order change says: with fresh data (S2) keeps |P_i - P_j| >= D_s exactly
in discrete time. The margin v tau_j covers where j can have gone since its pose was taken; E_ij (the
two tangents +-t in 2-D, the four +-t1 +-t2 in 3-D) makes the row hold for every direction to j that
the data allow (within theta_j of n_ij). The least n . u over that cone is on its rim,
c_j n_ij . u - s_j |u_perp|, which the tilted rows bound (exactly in 2-D, from the safe side in 3-D,
as |t1.u| + |t2.u| >= |u_perp|), unless -u is inside the cone: then it is -|u|, and the first row
(|u| <= -n_ij . u / c_j there) bounds it: ``docs/safety.md``. With fresh data s_j = 0 and (S2) is one
row. An agent on the free clock, whose neighbours tick on their own timers, adds one period T to the age
it measures. A unicycle is guarded at its point l ahead of its axle: a pair's D_s grows by l_i + l_j and
an obstacle's D_o by l_i (:func:`widening`; the Robotarium's unicycle mapping).

- Every right side is >= 0, so u = 0 (stop) is always feasible: the set is never empty, and the
  projection of u^ onto a convex set holding 0 is never longer than u^, so the speed limit holds.
- A neighbour pose older than ``max_age`` (the age at which D'_j reaches the sensing radius: j may be
  anywhere the agent senses), or so old that j may be on any side (v tau_j >= |psi_ij|), whose row
  could bind: the agent brakes (u = 0).
- (S1) is solved exactly (:func:`project`): the optimum is the projection of u^ onto the affine set of
  at most D linearly independent active rows (KKT and Caratheodory), so every such set is tried and
  the closest command that satisfies every row is kept; u = 0 is always among the candidates. No
  iteration, nothing stopped early: a returned command satisfies its rows to rounding.

Everything is vectorized: rows are a flat list (row r belongs to agent ``agent[r]``), for one agent,
a swarm or a batch of swarms flattened.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations
from typing import NamedTuple

import numpy as np

from zswarm.args import SAFETY_MODES

MODES: tuple[str, ...] = SAFETY_MODES
TOL = 1e-12  # a candidate satisfies a row when a.u - b <= TOL (rounding of the exact solutions)
STALL_SHARE = 0.1  # an agent is stalled when the filter left it under this share of the law's speed
DETOUR = math.pi / 4  # a stalled agent tries the law's command turned this far to its right (the detour)
HAIR = 1e-6  # D_s and D_o are kept this share above the touching distances
_CHUNK = 256  # agents solved at once (bounds the candidates' memory)


def parse_mode(text: object) -> str:
    if not isinstance(text, str) or text.strip() not in MODES:
        raise ValueError(f"--safety must be one of {', '.join(MODES)} (got {text!r})")
    return text.strip()


@dataclass(frozen=True)
class Safety:
    """The filter's numbers (``docs/safety.md``): D_s, D_o, v, T, kappa, and the largest data age."""

    distance: float  # D_s: centres closer than this collide (2 d^r)
    clearance: float  # D_o: the body's radius, kept off an obstacle's boundary
    v_max: float
    period: float  # T: how long a command is held
    sensing_radius: float
    kappa: float = 1.0

    @property
    def max_age(self) -> float:
        """The oldest neighbour data the guarantee holds for: the age at which D'_j reaches the sensing
        radius (beyond it, j may be anywhere within the agent's sensing disc). Below 0 (a sensing
        radius under D_s): no data is young enough, and an agent brakes whenever a row binds."""
        return (self.sensing_radius - self.distance) / self.v_max

    def margin(self, age: np.ndarray | float) -> np.ndarray | float:
        """D'_j of (S2): the collision distance and what j can have moved since its pose."""
        return self.distance + self.v_max * np.asarray(age)


def widening(lookahead: np.ndarray | float) -> np.ndarray | float:
    """What a body steered at its point ``lookahead`` ahead of its axle adds to the distances the filter
    keeps (the Robotarium's unicycle mapping; ``docs/safety.md``): l_i + l_j to a pair's, l_i to an
    obstacle's, kept the same share above touching as the distances themselves."""
    return np.asarray(lookahead, dtype=float) * (1.0 + HAIR)


def safety_for(params, dt: float, lookahead: float = 0.0) -> Safety:
    """The filter of a parameter set at control period ``dt``. ``lookahead`` (every body a unicycle with
    its tracked point that far ahead of its axle): the distances grow by 2 l and l; a swarm of mixed
    bodies keeps them bare and widens each row by its own bodies' (:func:`widening`)."""
    s = params.swarm
    hair = 1.0 + HAIR  # the filter holds D_s exactly in exact arithmetic; rounding must not count a collision
    return Safety((2.0 * s.robot_radius + 2.0 * lookahead) * hair, (s.robot_radius + lookahead) * hair, s.v_max, dt,
                  s.sensing_radius)


class Rows(NamedTuple):
    """The constraints a . u <= b: row r belongs to agent ``agent[r]``; ``stale`` marks agents that
    must brake (a neighbour older than the guarantee's bound that could bind)."""

    agent: np.ndarray  # (R,)
    a: np.ndarray  # (R, D)
    b: np.ndarray  # (R,)
    stale: np.ndarray  # (N,) bool


def rows(safety: Safety, n: int, agent: np.ndarray, psi: np.ndarray, age: np.ndarray,
         obstacle_agent: np.ndarray, psi_o: np.ndarray, radius_o: np.ndarray,
         widen: np.ndarray | float = 0.0, widen_o: np.ndarray | float = 0.0) -> Rows:
    """(S2) for every pair (``agent``, ``psi`` = P_i - P_j as believed, ``age`` tau_j) and (S3) for every
    sensed obstacle (``obstacle_agent``, ``psi_o`` = P_i - C_o, ``radius_o``), of n agents. ``widen``,
    ``widen_o``: what each row adds to D_s and D_o (a unicycle steered at its point ahead of its axle:
    l_i + l_j for a pair, l_i for an obstacle; :func:`widening`)."""
    rate, v = safety.kappa / safety.period, safety.v_max
    age = np.asarray(age, dtype=float)
    d = np.linalg.norm(psi, axis=-1)
    b = 0.5 * rate * np.maximum(d - safety.margin(age) - widen, 0.0)
    spread = np.minimum(np.divide(v * age, d, out=np.ones_like(d), where=d > 0), 1.0)  # s_j
    cos = np.sqrt(1.0 - spread**2)
    unit = _unit(psi, d)
    a, owner, bb = [-unit], [agent], [cos * b]
    tilted = spread > 0
    for e in _tangent_signs(unit[tilted]):  # one row per sign pattern, where the data have an age
        a.append(-(cos[tilted, None] * unit[tilted] - spread[tilted, None] * e))
        owner.append(agent[tilted])
        bb.append(b[tilted])
    norm_a = np.sqrt(1.0 + (psi.shape[-1] - 2) * spread**2)  # |c n - s e|: 1 in 2-D, with |e|^2 = 2 in 3-D
    could_bind = cos * b < v * norm_a  # a row with b >= |a| v_max never binds a command no longer than v_max
    old = ((age > safety.max_age - np.asarray(widen) / v) | (v * age >= d)) & could_bind
    stale = np.zeros(n, dtype=bool)
    stale[agent[old]] = True
    dist_o = np.linalg.norm(psi_o, axis=-1)
    b_o = rate * np.maximum(dist_o - radius_o - safety.clearance - widen_o, 0.0)
    return Rows(np.concatenate([*owner, obstacle_agent]).astype(np.intp),
                np.concatenate([*a, -_unit(psi_o, dist_o)]), np.concatenate([*bb, b_o]), stale)


def _tangent_signs(unit: np.ndarray) -> list[np.ndarray]:
    """The E_ij of (S2) for unit directions (R, D): +-t in 2-D; +-t1 +-t2 in 3-D (then
    |t1.u| + |t2.u| >= |u_perp| keeps the rows on the safe side); the first is 0 (the plain row)."""
    if unit.shape[-1] == 2:
        t = np.stack([-unit[:, 1], unit[:, 0]], axis=-1)
        return [t, -t]
    t1, t2 = _basis3(unit)
    return [t1 + t2, t1 - t2, -t1 + t2, -t1 - t2]


def _basis3(unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to each row of ``unit`` and to each other."""
    axis = np.zeros_like(unit)
    axis[np.arange(len(unit)), np.argmin(np.abs(unit), axis=-1)] = 1.0
    t1 = np.cross(unit, axis)
    t1 = _unit(t1, np.linalg.norm(t1, axis=-1))
    return t1, np.cross(unit, t1)


def _unit(v: np.ndarray, norm: np.ndarray) -> np.ndarray:
    """v / |v|; a zero offset (coincident centres) gets no direction and its row reads 0 <= b."""
    return np.divide(v, norm[:, None], out=np.zeros_like(v, dtype=float), where=norm[:, None] > 0)


class Filtered(NamedTuple):
    command: np.ndarray  # (N, D) the filtered commands
    acted: np.ndarray  # (N,) the filter changed the command
    stalled: np.ndarray  # (N,) ... to under STALL_SHARE of the law's speed
    braked: np.ndarray  # (N,) stopped: data older than the guarantee's bound


    def flags(self) -> np.ndarray:
        """Each agent's flag of ``messages.SAFETY_FLAGS``: 0 passed, 1 filtered, 2 stalled, 3 braked."""
        return np.where(self.braked, 3, np.where(self.stalled, 2, self.acted.astype(int)))


def apply(u_hat: np.ndarray, r: Rows, detour: bool = True) -> Filtered:
    """(S1) for every agent: the exact projection of its command, braking where ``r.stale`` says; with
    ``detour``, a stalled agent takes the detour where it goes farther (:func:`take_detour`)."""
    u = project(u_hat, r.agent, r.a, r.b)
    if detour:
        u = take_detour(u_hat, u, r)
    u[r.stale] = 0.0
    return judged(u_hat, u, r.stale.copy())


def turn_right(u: np.ndarray) -> np.ndarray:
    """Commands (..., D) turned by :data:`DETOUR` clockwise about the vertical (z stays)."""
    c, s = math.cos(DETOUR), math.sin(DETOUR)
    out = np.array(u, dtype=float, copy=True)
    out[..., 0], out[..., 1] = c * u[..., 0] + s * u[..., 1], -s * u[..., 0] + c * u[..., 1]
    return out


def take_detour(u_hat: np.ndarray, u: np.ndarray, r: Rows) -> np.ndarray:
    """The right-hand rule against deadlock (D1 of ``docs/safety.md``): an agent the projection stalled
    (under :data:`STALL_SHARE` of the law's speed) projects the law's command turned right by
    :data:`DETOUR` onto the same rows, and keeps that where it is the longer (beyond rounding). Both
    satisfy every row, so the guarantee is the same; two agents facing each other both turn right and
    slide past."""
    speed = np.linalg.norm(u_hat, axis=-1)
    stuck = np.flatnonzero((np.linalg.norm(u, axis=-1) < STALL_SHARE * speed) & ~r.stale)
    if len(stuck) == 0:
        return u
    sel = np.isin(r.agent, stuck)
    alt = project(turn_right(u_hat[stuck]), np.searchsorted(stuck, r.agent[sel]), r.a[sel], r.b[sel])
    better = np.linalg.norm(alt, axis=-1) > np.linalg.norm(u[stuck], axis=-1) + 1e-9 * speed[stuck]  # not a tie
    u[stuck[better]] = alt[better]
    return u


def judged(u_hat: np.ndarray, u: np.ndarray, braked: np.ndarray) -> Filtered:
    """What a filter did to the commands ``u_hat``, leaving ``u``: changed them, stalled them (under
    :data:`STALL_SHARE` of the law's speed), braked them."""
    change = np.linalg.norm(u - u_hat, axis=-1)
    speed = np.linalg.norm(u_hat, axis=-1)
    acted = change > 1e-9 * np.maximum(speed, 1.0)
    stalled = acted & (np.linalg.norm(u, axis=-1) < STALL_SHARE * speed)
    return Filtered(u, acted, stalled, braked)


def project(u_hat: np.ndarray, agent: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin |u - u^_i|^2 s.t. a_r . u <= b_r (rows of agent i), every b_r >= 0; exact (module doc)."""
    u = np.array(u_hat, dtype=float, copy=True)
    if len(agent) == 0:
        return u
    slack = np.einsum("rd,rd->r", a, u[agent]) - b
    need = np.unique(agent[slack > TOL])
    if len(need) == 0:
        return u
    speed = np.linalg.norm(u, axis=-1)
    # a row with b >= |a| |u^| cannot bind: the projection onto a convex set holding 0 is no longer than u^
    keep = np.isin(agent, need) & (b < speed[agent] * np.linalg.norm(a, axis=-1) + TOL)
    for start in range(0, len(need), _CHUNK):
        chunk = need[start:start + _CHUNK]
        sel = keep & np.isin(agent, chunk)
        u[chunk] = _solve(u[chunk], np.searchsorted(chunk, agent[sel]), a[sel], b[sel])
    return u


def _solve(u_hat: np.ndarray, owner: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The exact projections of M commands (M, D), rows grouped by ``owner`` (0..M-1)."""
    m, dims = u_hat.shape
    order = np.argsort(owner, kind="stable")
    owner, a, b = owner[order], a[order], b[order]
    counts = np.bincount(owner, minlength=m)
    k = int(counts.max())
    slot = np.arange(len(owner)) - np.repeat(np.cumsum(counts) - counts, counts)
    A = np.zeros((m, k, dims))
    B = np.full((m, k), np.inf)
    A[owner, slot], B[owner, slot] = a, b
    valid = np.zeros((m, k), dtype=bool)
    valid[owner, slot] = True
    cands = [u_hat[:, None, :], np.zeros((m, 1, dims))]
    for size in range(1, min(dims, k) + 1):
        cands.append(_active_set_projections(u_hat, A, B, valid, size))
    c = np.concatenate(cands, axis=1)  # (M, Q, D)
    slack = np.einsum("mqd,mkd->mqk", c, A) - np.where(valid, B, 0.0)[:, None, :]
    ok = np.all(~valid[:, None, :] | (slack <= TOL), axis=-1) & np.all(np.isfinite(c), axis=-1)
    dist = np.where(ok, np.sum((c - u_hat[:, None, :]) ** 2, axis=-1), np.inf)
    return c[np.arange(m), np.argmin(dist, axis=1)]


def _active_set_projections(u_hat: np.ndarray, A: np.ndarray, B: np.ndarray, valid: np.ndarray,
                            size: int) -> np.ndarray:
    """For every set S of ``size`` rows: u^ - A_S^T (A_S A_S^T)^-1 (A_S u^ - b_S), the projection onto
    {a_r . u = b_r, r in S}; NaN where S is not a set of valid, linearly independent rows."""
    m, k, dims = A.shape
    sets = np.array(list(combinations(range(k), size)), dtype=np.intp)  # (S, size)
    AS = A[:, sets]  # (M, S, size, D)
    BS = np.where(valid, B, 0.0)[:, sets]
    gram = np.einsum("msid,msjd->msij", AS, AS)
    rhs = np.einsum("msid,md->msi", AS, u_hat) - BS
    det = np.linalg.det(gram)
    good = np.all(valid[:, sets], axis=-1) & (np.abs(det) > 1e-12)
    gram = np.where(good[..., None, None], gram, np.eye(size))
    lam = np.linalg.solve(gram, rhs[..., None])[..., 0]
    out = u_hat[:, None, :] - np.einsum("msid,msi->msd", AS, lam)
    out[~good] = np.nan
    return out


def guarantee(params, dt: float | None = None) -> dict:
    """What ``--safety barrier`` guarantees for a parameter set (the design report's Safety row): the
    distance it keeps, the oldest data it trusts, the speed limit and the body."""
    body = params.body.body
    if body == "double-integrator":
        return {"holds": False, "binding": False, "distance": None, "max_age": None,
                "detail": "not available for a double-integrator (it cannot stop within a step): runs refuse "
                          "--safety barrier and default to off"}
    lookahead = params.body.lookahead if body == "unicycle" else 0.0
    s = safety_for(params, dt or 0.05, lookahead)
    where = "its look-ahead points" if lookahead else "centres"
    detail = (f"with --safety barrier (the default for runs), {where} stay >= {s.distance:.4g} apart and >= "
              f"{s.clearance:.4g} off obstacles at speeds <= {s.v_max:g}, on neighbour data up to "
              f"{max(s.max_age, 0.0):.3g} s old (D'_j = D_s + v tau_j); older data, or a neighbour that may be on "
              "any side: the agent brakes")
    if lookahead:
        detail += "; a unicycle's turn-rate limit can make it lag the filtered command (measured, not proven)"
    return {"holds": s.max_age > 0, "distance": s.distance, "max_age": s.max_age, "detail": detail}
