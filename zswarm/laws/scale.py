"""The one rule that fits a published law to a scenario: the law computes in its own published units.

A law from the literature is published for drones a few tens of metres apart (Vásárhelyi et al. 2018:
r0_rep = 25 m, 6 m/s), for pixels (Reynolds' boids as in Shiffman's *Nature of Code*: 25 px, 2 px a
frame) or in bare numbers (Olfati-Saber 2006: d = 7). zswarm's scenarios are a few units across with
v_max about 1. Rather than re-deriving every parameter for every scenario, each law keeps its published
parameters verbatim and is evaluated in its published units:

    length  x_law = x / lambda,   lambda = the scenario's pair spacing d / the law's published spacing
    speed   v_law = v / sigma,    sigma  = the scenario's v_max / the law's published top speed
    time    t_law = t / tau,      tau    = lambda / sigma

so a published rate (1/s) stands for rate * sigma / lambda in the scenario, and an acceleration for
acc * sigma^2 / lambda. The law's velocity command is mapped back (times sigma) and the scenario's
v_max bounds it. ``zswarm laws --scenario NAME`` prints lambda, sigma and tau, and each parameter's
scenario value beside its published one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from zswarm.laws.contract import Context, Observations


@dataclass(frozen=True)
class Units:
    """lambda (scenario length per law length) and sigma (scenario speed per law speed)."""

    length: float = 1.0
    speed: float = 1.0

    @classmethod
    def fit(cls, context: Context, spacing: float, top_speed: float) -> Units:
        """The units that map a law published for ``spacing`` and ``top_speed`` onto ``context``."""
        return cls(context.spacing / spacing, context.v_max / top_speed)

    @property
    def time(self) -> float:
        """tau: scenario seconds per law second."""
        return self.length / self.speed

    def to_law(self, obs: Observations) -> Observations:
        """``obs`` in the law's units (positions, velocities, ages, dt, v_max)."""
        lam, sig, tau = self.length, self.speed, self.time
        return obs.replace(position=obs.position / lam, velocity=obs.velocity / sig,
                           neighbour_position=obs.neighbour_position / lam,
                           neighbour_velocity=obs.neighbour_velocity / sig, neighbour_age=obs.neighbour_age / tau,
                           obstacle_centre=obs.obstacle_centre / lam, obstacle_radius=obs.obstacle_radius / lam,
                           target=obs.target / lam, v_max=np.asarray(obs.v_max, dtype=float) / sig, dt=obs.dt / tau)

    def describe(self) -> dict[str, float]:
        return {"length": self.length, "speed": self.speed, "time": self.time}

    def scaled(self, value: float, dimension: str) -> float:
        """A published ``value`` of ``dimension`` (length, speed, rate, accel, time, 1/length^2, none) in
        scenario units."""
        lam, sig = self.length, self.speed
        factor = {"length": lam, "speed": sig, "rate": sig / lam, "accel": sig * sig / lam, "time": lam / sig,
                  "1/length^2": 1.0 / (lam * lam), "none": 1.0}[dimension]
        return value * factor
