"""Seeded, reproducible network faults, applied by each receiving agent to each incoming link.

A link is (receiver, source): a neighbour's poses, the prey, or the world's obstacle replies. Every
link draws from its own generator, ``numpy.random.default_rng([seed, receiver, source])``, so the
pattern of a link depends only on the seed and on how many messages crossed it, not on how messages
of different links interleave.

- delay: ``latency`` plus a uniform jitter in [-jitter, +jitter] (never below 0);
- Bernoulli dropout with probability ``dropout``;
- bursty loss (Gilbert-Elliott, when ``burst`` > 0): a good state that loses nothing and a bad state
  that loses everything, with mean bad-run length ``burst`` and stationary loss ``dropout``
  (P(bad -> good) = 1/burst, P(good -> bad) = dropout/((1 - dropout) burst));
- distance-dependent loss of poses: probability ``distance_loss * (d/R)^2`` at distance d.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np

from zswarm.args import duration_seconds

PREY_SOURCE = 2**31 - 1
OBSTACLE_SOURCE = 2**31 - 2


def parse_duration(text: str) -> float:
    """'100ms' or '0.1s' -> seconds (:func:`zswarm.args.duration_seconds`, in the two units a fault delay
    takes). A bare number is refused, but 0: it could be either unit."""
    value = duration_seconds(text, "s", ("ms", "s"))
    if value is None or value < 0:
        raise ValueError(f"expected a duration like 100ms or 0.1s (got {text!r})")
    if value and not re.search(r"(ms|s)\s*$", str(text)):
        raise ValueError(f"{text!r} needs a unit: {text}ms or {text}s")
    return value


def parse_duration_list(text: str) -> list[float]:
    """'0,50,100,200ms' -> seconds; a unit at the end applies to every bare number before it."""
    m = re.search(r"(ms|s)\s*$", text)
    unit = m.group(1) if m else ""
    return [parse_duration(part if re.search(r"(ms|s)\s*$", part) else part + unit)
            for part in text.split(",") if part.strip()]


@dataclass(frozen=True)
class FaultModel:
    latency: float = 0.0
    jitter: float = 0.0
    dropout: float = 0.0
    burst: float = 0.0
    distance_loss: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("latency", "jitter", "burst", "distance_loss"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name} must be a finite number >= 0 (got {v!r})")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1) (got {self.dropout!r})")
        if self.distance_loss > 1.0:
            raise ValueError(f"distance loss must be in [0, 1] (got {self.distance_loss!r})")
        if 0 < self.burst < 1:
            raise ValueError(f"burst (mean burst length) must be 0 or >= 1 (got {self.burst!r})")

    @property
    def active(self) -> bool:
        return any((self.latency, self.jitter, self.dropout, self.distance_loss))

    def requested(self) -> dict[str, float]:
        return {"latency_ms": self.latency * 1000, "jitter_ms": self.jitter * 1000, "dropout": self.dropout,
                "burst": self.burst, "distance_loss": self.distance_loss}


@dataclass
class Link:
    rng: np.random.Generator
    bad: bool = False


@dataclass
class LinkFaults:
    """Per-link decisions; pure given the seed and the order of messages on each link."""

    model: FaultModel
    receiver: int
    links: dict[int, Link] = field(default_factory=dict)
    dropped: int = 0
    passed: int = 0

    def link(self, source: int) -> Link:
        ln = self.links.get(source)
        if ln is None:
            ln = self.links[source] = Link(np.random.default_rng([self.model.seed, self.receiver, source]))
        return ln

    def decide(self, source: int, distance_ratio: float | None = None) -> float | None:
        """Delay in seconds for the next message of this link, or None if it is lost."""
        m, ln = self.model, self.link(source)
        u_loss, u_dist, u_jit = ln.rng.random(3)  # always three draws: the stream stays aligned
        if m.burst > 0 and m.dropout > 0:
            r = 1.0 / m.burst
            p = m.dropout * r / (1.0 - m.dropout)
            ln.bad = (u_loss >= r) if ln.bad else (u_loss < p)
            lost = ln.bad
        else:
            lost = u_loss < m.dropout
        if not lost and distance_ratio is not None and m.distance_loss > 0:
            lost = u_dist < m.distance_loss * distance_ratio**2
        if lost:
            self.dropped += 1
            return None
        self.passed += 1
        return max(m.latency + m.jitter * (2.0 * u_jit - 1.0), 0.0)
