"""The prey (the goal of the swarm) and how it moves: static, straight, circular or evasive.

Section 5: the target moves slower than the agents' top speed. :func:`step` advances the prey by one
time step from the state at the start of the step, so a simulator and the distributed world that call
it with the same inputs move the prey identically.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from zswarm.paper.numeric import all_finite

PreyKind = Literal["static", "straight", "circle", "evasive"]
PREY_KINDS: tuple[PreyKind, ...] = ("static", "straight", "circle", "evasive")


@dataclass(frozen=True)
class PreyMotion:
    """How the prey moves.

    - ``static``: stays at its start (Fig 13).
    - ``straight``: constant ``speed`` along ``heading_deg`` (in 3-D, climbing at ``climb_deg``).
    - ``circle``: constant ``speed`` on a circle of ``radius`` about ``center`` (counter-clockwise). In
      3-D the circle is horizontal, about ``center`` = (x, y, z), and the prey flies it rising and
      falling by ``bob``: z = z_c + bob sin(angle).
    - ``evasive``: flees the nearest agent it senses within ``sense_radius`` at ``speed``; it stays
      inside ``bounds`` (x_min, y_min, x_max, y_max), sliding along the edge it meets (in 3-D, any
      height).

    The dimension is the prey's own (its position's length): a 2-D run ignores ``climb_deg``, ``bob``
    and a third ``center`` coordinate.
    """

    kind: PreyKind = "static"
    speed: float = 0.0
    heading_deg: float = 0.0
    center: tuple[float, ...] = (0.0, 0.0)
    radius: float = 1.0
    sense_radius: float = 1.5
    bounds: tuple[float, float, float, float] = (-5.0, -5.0, 5.0, 5.0)
    climb_deg: float = 0.0
    bob: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in PREY_KINDS:
            raise ValueError(f"prey kind must be one of {', '.join(PREY_KINDS)} (got {self.kind!r})")
        for name in ("speed", "radius", "sense_radius"):
            value = getattr(self, name)
            if not (all_finite((value,)) and value >= 0):
                raise ValueError(f"prey {name} must be a finite number >= 0 (got {value!r})")
        for name, values in (("heading_deg", (self.heading_deg,)), ("center", self.center), ("bounds", self.bounds),
                             ("climb_deg", (self.climb_deg,)), ("bob", (self.bob,))):
            if not all_finite(values):
                shown = values if len(values) > 1 else values[0]
                raise ValueError(f"prey {name} must hold finite numbers (got {shown!r})")
        if len(self.center) not in (2, 3):
            raise ValueError(f"prey center must be [x, y] or [x, y, z] (got {self.center!r})")
        if self.kind == "circle" and self.radius <= 0:
            raise ValueError("prey radius must be > 0 for a circular prey")
        x0, y0, x1, y1 = self.bounds
        if not (x0 < x1 and y0 < y1):
            raise ValueError(f"prey bounds must be (x_min, y_min, x_max, y_max) with min < max (got {self.bounds})")


def step(motion: PreyMotion, prey: np.ndarray, dt: float, agents: np.ndarray) -> np.ndarray:
    """The prey's position after ``dt``, vectorized over runs: ``prey`` (..., D) and the agents' positions
    ``agents`` (..., N, D) (used only by the evasive prey), with any leading axes (none for one run,
    (B,) for a batch of runs that share this motion)."""
    prey = np.asarray(prey, dtype=float)
    if motion.kind == "static" or motion.speed == 0.0:
        return prey.copy()
    dims = prey.shape[-1]
    if motion.kind == "straight":
        h = math.radians(motion.heading_deg)
        if dims == 2:
            return prey + motion.speed * dt * np.array([math.cos(h), math.sin(h)])
        c = math.radians(motion.climb_deg)
        return prey + motion.speed * dt * np.array([math.cos(c) * math.cos(h), math.cos(c) * math.sin(h), math.sin(c)])
    if motion.kind == "circle":
        c = np.asarray(motion.center[:2], dtype=float)
        rel = prey[..., :2] - c
        angle = np.arctan2(rel[..., 1], rel[..., 0]) + motion.speed * dt / motion.radius
        flat = c + motion.radius * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
        if dims == 2:
            return flat
        z_c = motion.center[2] if len(motion.center) == 3 else 0.0
        return np.concatenate([flat, (z_c + motion.bob * np.sin(angle))[..., None]], axis=-1)
    # evasive: flee the nearest agent within sense_radius, stay inside the bounds (any height in 3-D)
    agents = np.asarray(agents, dtype=float).reshape(prey.shape[:-1] + (-1, dims))
    if agents.shape[-2] == 0:
        return prey.copy()
    away = prey[..., None, :] - agents
    dist = np.sqrt(np.einsum("...ij,...ij->...i", away, away))
    k = np.argmin(dist, axis=-1)
    nearest = np.take_along_axis(dist, k[..., None], axis=-1)[..., 0]
    flee = (nearest <= motion.sense_radius) & (nearest > 0.0)
    toward = np.take_along_axis(away, k[..., None, None], axis=-2)[..., 0, :]
    moved = prey + motion.speed * dt * toward / np.where(flee, nearest, 1.0)[..., None]
    x0, y0, x1, y1 = motion.bounds
    moved = np.concatenate([np.clip(moved[..., :1], x0, x1), np.clip(moved[..., 1:2], y0, y1), moved[..., 2:]],
                           axis=-1)
    return np.where(flee[..., None], moved, prey)
