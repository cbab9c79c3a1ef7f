"""What a commanded velocity does: the body an agent moves, written once for every runner.

The control law (eq 5 / eq 36 with the speed limit) is pure: what an agent sensed in, a desired
velocity ``v_d`` out. The paper's agent is "the omni-directional robot without nonholonomic
constraints", so its body moves exactly as commanded. Real robots do not, and a body says how:

- ``point`` (the paper's, the default): the velocity is the command, ``P_{k+1} = P_k + dt v_d``.
- ``unicycle``: a differential-drive robot with heading theta. It tracks ``v_d`` with the point
  ``lookahead`` ahead of its axle (feedback linearization, Oriolo, De Luca & Vendittelli 2002):

      u     = cos(theta) v_dx + sin(theta) v_dy             forward speed, |u| <= v_max
      omega = (-sin(theta) v_dx + cos(theta) v_dy) / l      turn rate, |omega| <= turn_rate

  and moves along its heading only: ``P_{k+1} = P_k + dt u (cos theta, sin theta)``,
  ``theta_{k+1} = theta_k + dt omega``. It never moves sideways.
- ``double-integrator``: a mass (a drone): its velocity changes by at most ``accel`` per second,
  toward the command: ``v_{k+1} = v_k + dt clip((v_d - v_k) / dt, accel)``, ``P_{k+1} = P_k + dt v_{k+1}``.
  With an unbounded ``accel`` it would be the point body; with a finite one it cannot stop at once.

Every function is pure and vectorized over any leading shape (one agent, a swarm, a batch of swarms);
the body's parameters may be scalars or arrays that broadcast over the leading shape. The agent
process, the reference simulator and the batched simulator all move through :func:`step`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from zswarm.errors import ParamError
from zswarm.paper.params import HEADED, KINDS, parse_body  # noqa: F401 - a body's names are parameters

@dataclass(frozen=True)
class BodySpec:
    """A body and its limits. Arrays (one value per run of a batch) broadcast over the leading shape."""

    kind: str = "point"
    v_max: float | np.ndarray = 1.0
    turn_rate: float | np.ndarray = 4.0  # unicycle: rad/s
    lookahead: float | np.ndarray = 0.25  # unicycle: distance of the tracked point ahead of the axle
    accel: float | np.ndarray = 2.0  # double-integrator: the largest |dv/dt|

    @property
    def headed(self) -> bool:
        return self.kind in HEADED


class BodyState(NamedTuple):
    """Where the bodies are, the velocity each last moved with, and each one's heading (NaN: none)."""

    position: np.ndarray  # (..., 2)
    velocity: np.ndarray  # (..., 2)
    heading: np.ndarray  # (...,)


def start(spec: BodySpec, positions: np.ndarray, facing: np.ndarray) -> BodyState:
    """Bodies at rest at ``positions``; a headed body faces the point ``facing`` (its first goal)."""
    positions = np.asarray(positions, dtype=float)
    if spec.headed:
        d = np.asarray(facing, dtype=float) - positions
        heading = np.arctan2(d[..., 1], d[..., 0])
    else:
        heading = np.full(positions.shape[:-1], np.nan)
    return BodyState(positions, np.zeros_like(positions), heading)


def velocity(spec: BodySpec, state: BodyState, v_d: np.ndarray, dt: float) -> np.ndarray:
    """The velocity each body moves with this step when commanded ``v_d`` (the point body: ``v_d``)."""
    if spec.kind == "point":
        return v_d
    if spec.kind == "unicycle":
        return _unicycle(spec, state.heading, v_d)[0]
    if spec.kind == "double-integrator":
        return state.velocity + dt * _limit((v_d - state.velocity) / dt, spec.accel)
    raise ParamError(f"unknown body {spec.kind!r}")


def step(spec: BodySpec, state: BodyState, v_d: np.ndarray, dt: float) -> BodyState:
    """One explicit Euler step of every body under the command ``v_d``."""
    if spec.kind == "unicycle":
        v, omega = _unicycle(spec, state.heading, v_d)
        return BodyState(state.position + dt * v, v, wrap(state.heading + dt * omega))
    v = velocity(spec, state, v_d, dt)
    return BodyState(state.position + dt * v, v, state.heading)


def tracked_point(position, heading, lookahead: float):
    """Where a headed body is steered and guarded: P + l (cos theta, sin theta), the unicycle's point
    ``lookahead`` ahead of its axle (P itself without a heading or a look-ahead). The one home of that
    point: the reference simulator's filter takes it for the whole swarm (arrays with any leading
    axes), an agent for itself and each neighbour it guards (a tuple in, a tuple out)."""
    if heading is None or (np.ndim(lookahead) == 0 and not lookahead):
        return position
    if isinstance(position, tuple):
        return (position[0] + lookahead * math.cos(heading), position[1] + lookahead * math.sin(heading),
                *position[2:])
    out = np.array(position, dtype=float, copy=True)
    out[..., 0] += lookahead * np.cos(heading)
    out[..., 1] += lookahead * np.sin(heading)
    return out


def wrap(angle: np.ndarray) -> np.ndarray:
    """An angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def unicycle_inputs(spec: BodySpec, heading: np.ndarray, v_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A unicycle's forward speed u and turn rate omega (each clipped to its limit) that steer the point
    ``lookahead`` ahead of its axle along ``v_d``: what a differential-drive robot is sent."""
    c, s = np.cos(heading), np.sin(heading)
    v_max, w_max = np.asarray(spec.v_max), np.asarray(spec.turn_rate)
    u = np.clip(c * v_d[..., 0] + s * v_d[..., 1], -v_max, v_max)
    omega = np.clip((-s * v_d[..., 0] + c * v_d[..., 1]) / np.asarray(spec.lookahead), -w_max, w_max)
    return u, omega


def _unicycle(spec: BodySpec, heading: np.ndarray, v_d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The velocity u (cos theta, sin theta) a unicycle moves with and its turn rate omega
    (:func:`unicycle_inputs`)."""
    u, omega = unicycle_inputs(spec, heading, v_d)
    return u[..., None] * np.stack([np.cos(heading), np.sin(heading)], axis=-1), omega


def _limit(a: np.ndarray, bound: float | np.ndarray) -> np.ndarray:
    """Each vector of ``a`` shortened to at most ``bound`` (its direction kept)."""
    norm = np.sqrt(np.einsum("...k,...k->...", a, a))
    scale = np.minimum(1.0, np.asarray(bound) / np.where(norm > 0.0, norm, 1.0))
    return a * scale[..., None]
