"""What one agent asks of the network: the cells it listens to, the obstacles near it, the latency
probe's subscription and, in lockstep, the poses of a step it still lacks.

The outbound half of sensing. Everything asked for comes back through the bridge's one inbound chain
into :class:`agents.sensing.Sensing` (replies to a query asked without an event loop join the inbox,
to be taken in at a later tick like any other sample).

Cells: those the sensing disc (ball), grown by 2 v_max dt, overlaps (:mod:`agents.cell_view`).
Obstacles: asked of the world's queryable within 2R of where the agent is, again after it moved R
(:mod:`agents.obstacle_view`).
"""

from __future__ import annotations

import asyncio
import math
import time

from agents.cell_view import CellView
from agents.sensing import Sensing
from zswarm.paper.neighbours import step_reach
from zswarm.net.bridge import Bridge
from zswarm.net.keys import cells_in_disc


#: How often a member token the safety filter relies on alone is asked about again, at most (seconds).
MEMBER_CHECK_S = 1.0


class Outreach:
    def __init__(self, sensing: Sensing, bridge: Bridge) -> None:
        self.sensing, self.bridge, self.keys = sensing, bridge, sensing.keys
        self.cell_view = CellView(self.keys, bridge, sensing.body, sensing.subscription_radius)
        self.asking: set[tuple[int, ...]] = set()  # cells asked for their agents, answers not all in
        self.member_asked: dict[tuple[int, tuple[int, ...]], float] = {}  # (id, cell) -> when its token was asked about
        self.followed_at: tuple[float, ...] | None = None  # where it followed its cells last

    @property
    def cells(self) -> dict[tuple[int, ...], object]:
        return self.cell_view.cells

    # --- without an event loop (the free clock): ask, and take the answers in at a later tick -------

    def request_obstacles(self, now: float, timeout: float = 2.0) -> None:
        self.sensing.obstacle_view.request(self.bridge, now, timeout)

    def follow_cells(self, ask: bool = False) -> None:
        """Listen to the cells the sensing disc overlaps, and ask each new cell who sits in it. Its agents'
        poses are asked for at once (the cells whose answers are not all in yet: :attr:`asking`) where it
        could not have heard them coming: at its start, after a jump (more than 2 v_max dt since the last
        tick: a robot's odometry reset) and when ``ask`` (a takeover's state). A cell that a moving
        agent's disc, grown by 2 v_max dt, has just reached holds nobody within R + v_max dt, and its
        agents speak again before they can be within R: asking would cost each of them an answer, and
        a moving swarm's agents a third of their tick, for nothing."""
        s = self.sensing
        point, last = s.body.position, self.followed_at
        self.followed_at = point
        new, left = self.cell_view.move()
        unanswered = s.membership.unanswered
        if unanswered:  # a cell's ask that no reply came to: asked again, or who sits there is never known
            for key in unanswered:
                self.bridge.tokens_into_inbox(key, "in-now", 1.0, unanswered="in-unanswered",
                                              answered="in-answered")
            unanswered.clear()
        if not new and not left:
            return  # most ticks
        s.membership.listen_to(new, left)
        ask = ask or last is None or math.dist(point, last) > 2.0 * s.v_max * s.dt
        for cell in new:
            # who sits in it already (its live member tokens were subscribed first: Sensing._member)
            self.bridge.tokens_into_inbox(self.keys.cell_members(cell), "in-now", 1.0, unanswered="in-unanswered",
                                          answered="in-answered")
            if ask:
                self.asking.add(cell)
                self.bridge.get_into_inbox(self.keys.cell_poses(cell), "pose", 1.0,
                                           done=lambda cell=cell: self.asking.discard(cell))

    def check_members(self, now: float) -> None:
        """Ask again about the member tokens on which the safety filter's verdict on a silent neighbour
        rests (:attr:`agents.membership.Membership.doubted`): one nobody holds is a sign it left that cell
        (:meth:`agents.membership.Membership.member_gone`). Each token at most once every
        :data:`MEMBER_CHECK_S` seconds."""
        s = self.sensing.membership
        if not s.doubted:
            return  # most ticks
        for who, cells in s.doubted.items():
            for cell in cells:
                if now - self.member_asked.get((who, cell), -math.inf) >= MEMBER_CHECK_S:
                    self.member_asked[(who, cell)] = now
                    self.bridge.token_absent_into_inbox(self.keys.member(cell, who), "in-gone", 1.0)
        s.doubted.clear()

    def follow_probe(self, now: float) -> None:
        """Ring-channel inbox: keep the latency probe on the nearest live neighbour, in its windows
        (:mod:`agents.probe`)."""
        if self.sensing.latency_from_probe:
            self.sensing.latency_probe.follow(self.bridge, now)

    # --- on an event loop (lockstep) ----------------------------------------------------------------

    async def refresh_obstacles(self, timeout: float = 2.0) -> bool:
        return await self.sensing.obstacle_view.refresh(self.bridge, timeout)

    async def update_cells(self) -> None:
        """Subscribe to the cells the sensing disc overlaps; ask new cells for their agents at once."""
        new, left = self.cell_view.move()
        self.sensing.membership.listen_to(new, left)
        for cell in new:
            for key, payload in await self.bridge.get(self.keys.cell_poses(cell), timeout=1.0):
                self.sensing.handle(("pose", key, payload, False, time.time()))

    async def await_step_poses(self, step: int, wait: float) -> None:
        """Make sure it has the step pose of every agent that can be within its radius now.

        It subscribes to the cells within R + 2 v_max dt, so every agent that can be within R at
        step k was heard at step k-1. It waits (up to ``wait`` seconds) for those; for any still
        missing, and for cells it subscribed to during this step (a subscription may reach the router
        after a neighbour published), it asks the cells where they can be for their pose of this step.
        """
        s = self.sensing
        reach = s.subscription_radius
        expected = [nb for nb in s.neighbours.entries.values()
                    if step not in nb.by_step and (step - 1 in nb.by_step or nb.latest.step >= step - 1)
                    and s.body.distance(nb.latest) <= reach]
        loop = asyncio.get_running_loop()
        deadline = loop.time() + wait
        while expected and loop.time() < deadline:
            s.pose_arrived.clear()
            try:
                await asyncio.wait_for(s.pose_arrived.wait(), deadline - loop.time())
            except asyncio.TimeoutError:
                break
            expected = [nb for nb in expected if step not in nb.by_step]
        cells = {c for c, since in self.cell_view.since.items() if since >= step}
        for nb in expected:
            cells |= cells_in_disc(self.keys, nb.latest.position, step_reach(s.v_max, s.dt))
        replies = await asyncio.gather(*(self.bridge.get(f"{self.keys.cell_poses(c)}?step={step}", timeout=1.0)
                                         for c in cells))
        now = time.time()
        for key, payload in (r for batch in replies for r in batch):
            s.handle(("pose", key, payload, False, now))
