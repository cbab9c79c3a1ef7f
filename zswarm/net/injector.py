"""Seeded fault injection on an agent's inbound links, on the event loop (see :mod:`zswarm.model.faults`
for the per-link decisions and :class:`zswarm.net.bridge.Bridge` for where it sits)."""

from __future__ import annotations

import asyncio
from typing import Callable

from zswarm.model.faults import FaultModel, LinkFaults


class FaultInjector:
    """Sits between the Zenoh bridge and an agent's event loop (see :class:`zswarm.net.bridge.Bridge`)."""

    def __init__(self, model: FaultModel, receiver: int, loop: asyncio.AbstractEventLoop,
                 put: Callable, source_of: Callable[[str, str, bytes], tuple[int, float | None] | None]) -> None:
        self.faults = LinkFaults(model, receiver)
        self.loop, self.put, self.source_of = loop, put, source_of

    def deliver(self, item: tuple[str, str, bytes, bool]) -> None:
        src = self.source_of(*item[:3]) if not item[3] else None
        if src is None:  # liveliness, ticks, control: not subject to faults
            self.put(item)
            return
        delay = self.faults.decide(*src)
        if delay is None:
            return
        if delay > 0:
            self.loop.call_later(delay, self.put, item)
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
