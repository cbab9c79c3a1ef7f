"""What one agent knows of the obstacles: asked of the world's queryable within 2R of where it is, and
asked again once it has moved R from there (never the whole map)."""

from __future__ import annotations

import math

from agents.counters import Counters
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge
from zswarm.net.keys import Keys


class ObstacleView:
    def __init__(self, keys: Keys, bridge: Bridge, body, radius: float, counters: Counters) -> None:
        self.keys, self.bridge, self.body, self.radius, self.counters = keys, bridge, body, radius, counters
        self.obstacles: list[tuple[float, float, float]] = []  # centre x, y and radius of each known one
        self.query_at: tuple[float, float] | None = None  # where the answer it holds was asked
        self.query: tuple[float, float, float] | None = None  # (x, y, sent at): a query in flight

    async def refresh(self, timeout: float = 2.0) -> bool:
        """Ask the world for the obstacles within 2R; re-ask after moving R from the last question."""
        x, y = self.body.x, self.body.y
        if self.current():
            return True
        try:
            replies = await self.bridge.get(self.keys.obstacle_query(x, y, 2.0 * self.radius), timeout)
        except Exception:
            replies = []
        for _, payload in replies:
            try:
                m = msg.decode(payload)
            except msg.DecodeError as exc:
                self.counters.rejections.add(exc.reason, str(exc))
                continue
            if isinstance(m, msg.Obstacles):
                self.know(m, (x, y))
                return True
        self.counters.obstacle_queries_failed += 1
        return False  # keep what it knew (world away)

    def current(self) -> bool:
        """It knows the obstacles around it: asked less than R from where it is now."""
        at = self.query_at
        return at is not None and math.dist((self.body.x, self.body.y), at) < self.radius

    def know(self, m: msg.Obstacles, asked_at: tuple[float, float]) -> None:
        """The world's answer to a query made at ``asked_at``: the obstacles within 2R of there."""
        self.obstacles = [(cx, cy, r) for (cx, cy), r in zip(m.centers, m.radii)]
        self.query_at = asked_at

    def answered(self, m: msg.Obstacles) -> None:
        """The answer to the query in flight, taken in with the samples (no event loop)."""
        self.know(m, self.query[:2])
        self.query = None

    def request(self, now: float, timeout: float = 2.0) -> None:
        """Without an event loop: ask the world for the obstacles within 2R when it has moved R from
        the last answer (or has none); the answer is taken in with the next samples. An unanswered
        query counts as failed after ``timeout`` seconds and is asked again."""
        x, y = self.body.x, self.body.y
        if self.query is not None:
            if now - self.query[2] < timeout:
                return
            self.counters.obstacle_queries_failed += 1
            self.query = None
        if self.current():
            return
        self.query = (x, y, now)
        self.bridge.get_into_inbox(self.keys.obstacle_query(x, y, 2.0 * self.radius), "obstacles", timeout)
