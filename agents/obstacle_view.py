"""What one agent knows of the obstacles: asked of the world's queryable within 2R of where it is, and
asked again once it has moved R from there (never the whole map).

The answer says the world's dimension: an answer of the other one (a 2-D agent in a 3-D run, or the
reverse) is refused and remembered in :attr:`ObstacleView.foreign_dims`, which the agent turns into one
line and exit code 2 before it joins the swarm.
"""

from __future__ import annotations

import math

import numpy as np

from agents.counters import Counters
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge
from zswarm.net.keys import Keys


class ObstacleView:
    def __init__(self, keys: Keys, body, radius: float, counters: Counters) -> None:
        self.keys, self.body, self.radius, self.counters = keys, body, radius, counters
        self.obstacles: list[tuple[float, ...]] = []  # centre (x, y[, z]) and radius of each known one
        self.centers = np.zeros((0, keys.dims))  # the same as arrays (the vectorized law's input)
        self.radii = np.zeros(0)
        self.query_at: tuple[float, ...] | None = None  # where the answer it holds was asked
        self.query: tuple[tuple[float, ...], float] | None = None  # (where, sent at): a query in flight
        self.foreign_dims: int | None = None  # the world answered in another dimension than the agent's

    async def refresh(self, bridge: Bridge, timeout: float = 2.0) -> bool:
        """Ask the world for the obstacles within 2R; re-ask after moving R from the last question."""
        point = self.body.position
        if self.current():
            return True
        try:
            replies = await bridge.get(self.keys.obstacle_query(point, 2.0 * self.radius), timeout)
        except Exception:
            replies = []
        for _, payload in replies:
            try:
                m = msg.decode(payload)
            except msg.DecodeError as exc:
                self.counters.rejections.add(exc.reason, str(exc))
                continue
            if isinstance(m, msg.Obstacles) and self.know(m, point):
                return True
        self.counters.obstacle_queries_failed += 1
        return False  # keep what it knew (world away)

    def current(self) -> bool:
        """It knows the obstacles around it: asked less than R from where it is now."""
        at = self.query_at
        return at is not None and math.dist(self.body.position, at) < self.radius

    def know(self, m: msg.Obstacles, asked_at: tuple[float, ...]) -> bool:
        """The world's answer to a query made at ``asked_at``: the obstacles within 2R of there (False,
        and nothing learnt, when the world is of another dimension)."""
        if m.dims != self.keys.dims:
            self.foreign_dims = m.dims
            self.counters.rejections.add("dimensions")  # counted quietly: the agent says why it stops
            return False
        self.obstacles = [(*c, r) for c, r in zip(m.centers, m.radii)]
        self.centers = np.array(m.centers, dtype=float).reshape(-1, self.keys.dims)
        self.radii = np.array(m.radii, dtype=float)
        self.query_at = asked_at
        return True

    def answered(self, m: msg.Obstacles) -> None:
        """The answer to the query in flight, taken in with the samples (no event loop)."""
        self.know(m, self.query[0])
        self.query = None

    def request(self, bridge: Bridge, now: float, timeout: float = 2.0) -> None:
        """Without an event loop: ask the world for the obstacles within 2R when it has moved R from
        the last answer (or has none); the answer is taken in with the next samples. An unanswered
        query counts as failed after ``timeout`` seconds and is asked again."""
        if self.query is not None:
            if now - self.query[1] < timeout:
                return
            self.counters.obstacle_queries_failed += 1
            self.query = None
        if self.current():
            return
        point = self.body.position
        self.query = (point, now)
        bridge.get_into_inbox(self.keys.obstacle_query(point, 2.0 * self.radius), "obstacles", timeout)
