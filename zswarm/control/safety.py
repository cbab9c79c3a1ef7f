"""The safety filter: the command closest to the law's that keeps every agent apart, on data of any age.

Agent i replaces the law's command u^ by argmin |u - u^|^2 subject to a_r . u <= b_r (S1): one row per
sensed neighbour j, (S2), with the margin D'_j = D_s + v tau_j and the cone rows that hold for every
direction the data's age allows, and one per sensed obstacle, (S3); a unicycle is guarded at its point
ahead of its axle (:func:`widening`), a body with inertia at its next velocity with both braking
distances kept, solved about the command that brakes it (S4). Every right side is >= 0 (about the
braking command, S4), so stopping is always feasible; data older than the bound brakes the agent.
(S1) is solved exactly by enumerating the active sets (:func:`project`). The derivations and what is
proven: ``docs/safety.md``. Everything is vectorized: rows are a flat list (row r belongs to agent
``agent[r]``), for one agent, a swarm or a batch of swarms flattened.
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
    must brake (a neighbour older than the guarantee's bound that could bind). With inertia (S4):
    ``held`` (N, D), the command that brakes each agent (0 for a body without inertia), which satisfies
    each of its rows unless it must brake; ``reach`` (N,), how far from its velocity ``velocity`` (N, D)
    its command may be, and ``cap`` the speed limit."""

    agent: np.ndarray  # (R,)
    a: np.ndarray  # (R, D)
    b: np.ndarray  # (R,)
    stale: np.ndarray  # (N,) bool
    held: np.ndarray | None = None
    velocity: np.ndarray | None = None
    reach: np.ndarray | None = None
    cap: float = math.inf


class Inertia(NamedTuple):
    """Agents with inertia (S4): each one's velocity now (N, D) and largest acceleration (N,; inf or 0:
    a body that stops at once); ``stop`` (R,): each pair's neighbour's braking distance (its bound from
    its velocity and age: :func:`neighbour_stop`)."""

    velocity: np.ndarray
    accel: np.ndarray
    stop: np.ndarray | float = 0.0


def stopping(speed: np.ndarray | float, accel: np.ndarray | float) -> np.ndarray:
    """s^2 / (2A): how far a body at speed s goes braking at A (no farther in the Euler steps of
    :mod:`zswarm.control.body`); 0 for a body that stops at once (A inf or 0)."""
    accel = np.asarray(accel, dtype=float)
    finite = np.isfinite(accel) & (accel > 0)
    return np.where(finite, np.asarray(speed, dtype=float) ** 2 / (2.0 * np.where(finite, accel, 1.0)), 0.0)


def neighbour_stop(velocity: np.ndarray, age: np.ndarray, accel: np.ndarray | float, v_max: float) -> np.ndarray:
    """A neighbour's braking distance now, from its velocity (..., D) heard ``age`` seconds ago: its speed
    has grown by at most A tau since, and is at most v_max (S4)."""
    accel = np.asarray(accel, dtype=float)
    grown = np.where(np.isfinite(accel), accel, 0.0) * np.asarray(age)  # a body that stops at once: none kept
    return stopping(np.minimum(np.linalg.norm(velocity, axis=-1) + grown, v_max), accel)


def rows(safety: Safety, n: int, agent: np.ndarray, psi: np.ndarray, age: np.ndarray,
         obstacle_agent: np.ndarray, psi_o: np.ndarray, radius_o: np.ndarray,
         widen: np.ndarray | float = 0.0, widen_o: np.ndarray | float = 0.0, inertia: Inertia | None = None) -> Rows:
    """(S2) for every pair (``agent``, ``psi`` = P_i - P_j as believed, ``age`` tau_j) and (S3) for every
    sensed obstacle (``obstacle_agent``, ``psi_o`` = P_i - C_o, ``radius_o``), of n agents. ``widen``,
    ``widen_o``: what each row adds to D_s and D_o (a unicycle steered at its point ahead of its axle:
    l_i + l_j for a pair, l_i for an obstacle; :func:`widening`). ``inertia``: (S4), for agents that
    cannot stop at once and neighbours that cannot."""
    rate, v = safety.kappa / safety.period, safety.v_max
    age = np.asarray(age, dtype=float)
    if inertia is not None:  # each braking distance is kept as well: the agent's own and its neighbour's
        own = stopping(np.linalg.norm(inertia.velocity, axis=-1), inertia.accel)
        widen = widen + own[agent] + inertia.stop
        widen_o = widen_o + own[obstacle_agent]
    d = np.linalg.norm(psi, axis=-1)
    b = 0.5 * rate * np.maximum(d - safety.margin(age) - widen, 0.0)
    spread = np.minimum(np.divide(v * age, d, out=np.ones_like(d), where=d > 0), 1.0)  # s_j
    cos = np.sqrt(1.0 - spread**2)
    unit = _unit(psi, d)
    dist_o = np.linalg.norm(psi_o, axis=-1)
    b_o = rate * np.maximum(dist_o - radius_o - safety.clearance - widen_o, 0.0)
    tilted = spread > 0
    rims = _tangent_signs(unit[tilted])
    if inertia is None:
        gain = extra = held = reach = None
    else:
        gain, extra, held, reach = _own_terms(safety, n, inertia, agent, b, obstacle_agent, b_o)
    a, owner, bb = [-unit + _scaled(gain, agent, cos)], [agent], [cos * (b + _at(extra, agent))]
    for e in rims:  # one row per sign pattern, where the data have an age
        a.append(-(cos[tilted, None] * unit[tilted] - spread[tilted, None] * e) + _scaled(gain, agent[tilted]))
        owner.append(agent[tilted])
        bb.append(b[tilted] + _at(extra, agent[tilted]))
    if inertia is None:
        norm_a = np.sqrt(1.0 + (psi.shape[-1] - 2) * spread**2)  # |c n - s e|: 1 in 2-D, with |e|^2 = 2 in 3-D
        could_bind = cos * b < v * norm_a  # a row with b >= |a| v_max never binds a command no longer than v_max
    else:  # any of the pair's rows, as they are
        could_bind = bb[0] < v * np.linalg.norm(a[0], axis=-1)
        for a_e, b_e in zip(a[1:], bb[1:]):
            could_bind[tilted] |= b_e < v * np.linalg.norm(a_e, axis=-1)
    old = ((age > safety.max_age - np.asarray(widen) / v) | (v * age >= d)) & could_bind
    stale = np.zeros(n, dtype=bool)
    stale[agent[old]] = True
    return Rows(np.concatenate([*owner, obstacle_agent]).astype(np.intp),
                np.concatenate([*a, -_unit(psi_o, dist_o) + _scaled(gain, obstacle_agent)]),
                np.concatenate([*bb, b_o + _at(extra, obstacle_agent)]), stale, held,
                None if inertia is None else np.asarray(inertia.velocity, dtype=float), reach, v)


def _own_terms(safety: Safety, n: int, inertia: Inertia, agent: np.ndarray, b: np.ndarray,
               obstacle_agent: np.ndarray, b_o: np.ndarray) -> tuple[np.ndarray, ...]:
    """(S4)'s terms of each agent's own velocity v and acceleration bound A: the gain v / (A T) its rows
    add to a, what they add to b, |v|^2 / (A T) - rho^2 / (2 A T), the command that brakes it, v - min(|v|,
    T A) v / |v|, and rho, how far from v its command may be: T A, less where its least share of a gap
    (``b``, ``b_o``) could not pay for that much (at low speed, near the edge: a body at rest keeps
    sqrt(kappa A gap) to move away)."""
    T = safety.period
    vel = np.asarray(inertia.velocity, dtype=float)
    accel = np.broadcast_to(np.asarray(inertia.accel, dtype=float), (n,))
    finite = np.isfinite(accel) & (accel > 0)
    A = np.where(finite, accel, 1.0)
    speed2 = np.einsum("nd,nd->n", vel, vel)
    least = np.full(n, np.inf)
    np.minimum.at(least, agent, b)
    np.minimum.at(least, obstacle_agent, b_o)
    step = (T * A) ** 2
    rho2 = np.where(np.isfinite(least), np.minimum(step, 2.0 * A * T * least + 2.0 * speed2), step)
    gain = np.where(finite[:, None], vel / (A * T)[:, None], 0.0)
    extra = np.where(finite, (speed2 - 0.5 * rho2) / (A * T), 0.0)
    speed = np.sqrt(speed2)
    slow = np.divide(np.minimum(speed, T * A), speed, out=np.ones_like(speed), where=speed > 0)
    held = np.where(finite[:, None], vel * (1.0 - slow)[:, None], 0.0)
    return gain, extra, held, np.where(finite, np.sqrt(rho2), np.inf)


def _scaled(gain: np.ndarray | None, agent: np.ndarray, by: np.ndarray | None = None) -> np.ndarray | float:
    if gain is None:
        return 0.0
    return gain[agent] if by is None else by[:, None] * gain[agent]


def _at(values: np.ndarray | None, agent: np.ndarray) -> np.ndarray | float:
    return 0.0 if values is None else values[agent]


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
    ``detour``, a stalled agent takes the detour where it goes farther (:func:`take_detour`). With
    inertia (``r.held``): :func:`apply_inertia`."""
    if r.held is not None:
        return apply_inertia(u_hat, r)
    u = project(u_hat, r.agent, r.a, r.b)
    if detour:
        u = take_detour(u_hat, u, r)
    u[r.stale] = 0.0
    return judged(u_hat, u, r.stale.copy())


def apply_inertia(u_hat: np.ndarray, r: Rows) -> Filtered:
    """(S4): the law's velocity as the body reaches it in one period (at most T A from its velocity), then
    the exact projection onto the rows about the braking command, which satisfies all of them (u - held
    is projected: the rows hold 0 there); an agent for which braking does not satisfy a row (at low speed
    near the edge, or data the bound cannot cover) brakes. The result is brought back along the segment
    from braking, within ``reach`` of its velocity and the speed limit (both hold at either end). A body that
    stops at once among them takes the detour as :func:`apply` has it."""
    held, vel, reach = r.held, r.velocity, r.reach
    step = np.where(np.isfinite(reach), reach, 0.0)
    free = ~np.isfinite(reach)  # a body that stops at once: the command as the law gave it
    gap = u_hat - vel
    norm = np.linalg.norm(gap, axis=-1)
    scale = np.where(free, 1.0, np.minimum(1.0, np.divide(step, norm, out=np.ones_like(norm), where=norm > 0)))
    wanted = np.where(free[:, None], u_hat, vel + gap * scale[:, None])
    shifted = r.b - np.einsum("rd,rd->r", r.a, held[r.agent])
    must = r.stale.copy()
    must[r.agent[shifted < -TOL]] = True
    u = held + project(wanted - held, r.agent, r.a, np.maximum(shifted, 0.0))
    if free.any():  # its rows are about 0 (held is 0)
        u = take_detour(wanted, u, r._replace(stale=must | ~free))
    u = _within(held, u, vel, np.where(free, np.inf, reach), r.cap)
    u[must] = held[must]
    return judged(wanted, u, must)


def _within(start: np.ndarray, end: np.ndarray, centre: np.ndarray, radius: np.ndarray, cap: float) -> np.ndarray:
    """The farthest point of each segment start -> end within ``radius`` of ``centre`` and ``cap`` of 0
    (each start is within both)."""
    w = end - start
    t = np.ones(len(w))
    for c, rad in ((centre, radius), (np.zeros_like(centre), np.full(len(w), cap))):
        q = start - c
        ww, qw, qq = (np.einsum("nd,nd->n", x, y) for x, y in ((w, w), (q, w), (q, q)))
        out = np.isfinite(rad) & (ww > 0) & (ww + 2 * qw + qq > rad**2)
        root = (-qw + np.sqrt(np.maximum(qw**2 - ww * (qq - np.where(np.isfinite(rad), rad, 0.0) ** 2), 0.0)))
        t = np.where(out, np.minimum(t, np.clip(np.divide(root, ww, out=np.zeros_like(ww), where=ww > 0), 0.0, 1.0)), t)
    return start + w * t[:, None]


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
    if body == "double-integrator":  # (S4): both braking distances at full speed within the sensing radius
        s = safety_for(params, dt or 0.05)
        stop = float(stopping(s.v_max, params.body.accel))
        oldest = s.max_age - 2.0 * stop / s.v_max
        detail = (f"with --safety barrier (the default for runs), centres stay >= {s.distance:.4g} apart and >= "
                  f"{s.clearance:.4g} off obstacles, each agent keeping its own and each neighbour's braking "
                  f"distance (v_max^2/(2 accel) = {stop:.4g} at full speed): the sensing radius "
                  f"{s.sensing_radius:g} leaves {s.sensing_radius - s.distance - 2.0 * stop:.4g} beyond both, "
                  f"neighbour data up to {max(oldest, 0.0):.3g} s old at full speed; older data: the agent brakes")
        return {"holds": oldest > 0, "distance": s.distance, "max_age": oldest, "detail": detail}
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
