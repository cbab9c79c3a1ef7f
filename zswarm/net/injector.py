"""Seeded fault injection on an agent's inbound links, on the event loop (see :mod:`zswarm.swarm.faults`
for the per-link decisions and :class:`zswarm.net.bridge.Bridge` for where it sits)."""

from __future__ import annotations

import asyncio
import heapq
import time
from typing import Callable

from zswarm.swarm.faults import FaultModel, LinkFaults
from zswarm.net.bridge import Inbound


class FaultInjector:
    """Sits between the Zenoh bridge and an agent (see :class:`zswarm.net.bridge.Bridge`).

    A delayed sample is handed on when its delay has passed: by the event loop (``loop`` given), or,
    for an agent without one, at the first :meth:`release` after it fell due."""

    def __init__(self, model: FaultModel, receiver: int, loop: asyncio.AbstractEventLoop | None,
                 put: Callable, source_of: Callable[[str, str, bytes], tuple[int, float | None] | None]) -> None:
        self.faults = LinkFaults(model, receiver)
        self.loop, self.put, self.source_of = loop, put, source_of
        self.held: list[tuple[float, int, Inbound]] = []  # (due, order, sample): a heap, without a loop
        self.order = 0

    def release(self, now: float) -> None:
        """Hand on every held sample whose time has come (no event loop)."""
        while self.held and self.held[0][0] <= now:
            self.put(heapq.heappop(self.held)[2])

    def deliver(self, item: Inbound) -> None:
        """Drop ``item`` or hand it on once its delay has passed since it arrived; it then arrives
        (its receipt time) that much later."""
        tag, key, payload, deleted, received = item
        src = self.source_of(tag, key, payload) if not deleted else None
        if src is None:  # liveliness, ticks, control: not subject to faults
            self.put(item)
            return
        delay = self.faults.decide(*src)
        if delay is None:
            return
        if delay > 0:
            due = received + delay
            late = (tag, key, payload, deleted, due)
            wait = due - time.time()  # a batch is drained up to one tick after it arrived
            if wait <= 0:
                self.put(late)
            elif self.loop is not None:
                self.loop.call_later(wait, self.put, late)
            else:
                self.order += 1
                heapq.heappush(self.held, (due, self.order, late))
        else:
            self.put(item)

    async def filter_replies(self, replies: list[tuple[str, bytes]]) -> list[tuple[str, bytes]]:
        """Query replies (obstacles, or poses asked of a cell) cross the same faulty links."""
        kept, longest = [], 0.0
        for reply in replies:
            src = self.source_of("reply", *reply)
            delay = self.faults.decide(*src) if src is not None else 0.0
            if delay is not None:
                kept.append(reply)
                longest = max(longest, delay)
        if longest > 0:
            await asyncio.sleep(longest)
        return kept
