"""The one bridge between asyncio and Zenoh.

Zenoh calls back on its own threads. :class:`Bridge` keeps those callbacks tiny: they hand the raw
payload to the event loop with ``loop.call_soon_threadsafe`` and never call back into Zenoh;
blocking ``get`` calls run in the loop's executor.
"""

from __future__ import annotations

import asyncio
from typing import Any, Callable

import zenoh

from zswarm.net.keys import parse_parameters

Inbound = tuple[str, str, bytes, bool]  # (tag, key, payload, is_delete)
Deliver = Callable[[Inbound], None]


class Bridge:
    """Zenoh callbacks -> one asyncio queue; blocking calls -> the executor.

    ``deliver`` (optional) replaces the direct hand-over; the fault injector uses it to delay or drop
    each inbound message on the event loop's thread.
    """

    def __init__(self, session: zenoh.Session, loop: asyncio.AbstractEventLoop,
                 queue: asyncio.Queue, deliver: Deliver | None = None) -> None:
        self.session = session
        self.loop = loop
        self.queue = queue
        self.deliver: Deliver = deliver or queue.put_nowait
        self.reply_filter: Callable[[list[tuple[str, bytes]]], Any] | None = None
        self.closed = False

    def _hand_over(self, tag: str):
        def callback(sample: Any) -> None:
            if self.closed:
                return
            item = (tag, str(sample.key_expr), sample.payload.to_bytes(),
                    sample.kind == zenoh.SampleKind.DELETE)
            try:
                self.loop.call_soon_threadsafe(self.deliver, item)
            except RuntimeError:  # loop closed during shutdown
                pass
        return callback

    def subscribe(self, key: str, tag: str) -> Any:
        return self.session.declare_subscriber(key, self._hand_over(tag))

    def subscribe_liveliness(self, key: str, tag: str) -> Any:
        return self.session.liveliness().declare_subscriber(key, self._hand_over(tag), history=True)

    def queryable(self, key: str, answer: Callable[[dict[str, str]], list[tuple[str, bytes]]]) -> Any:
        """``answer`` runs on a Zenoh thread: it must only read immutable data it was given."""
        def handler(query: Any) -> None:
            try:
                for reply_key, payload in answer(parse_parameters(query.parameters)):
                    query.reply(reply_key, payload)
            except Exception:  # a bad query must never take the process down
                pass
        return self.session.declare_queryable(key, handler)

    async def get(self, selector: str, timeout: float) -> list[tuple[str, bytes]]:
        def blocking() -> list[tuple[str, bytes]]:
            out = []
            for reply in self.session.get(selector, timeout=timeout):
                if reply.ok is not None:
                    out.append((str(reply.ok.key_expr), reply.ok.payload.to_bytes()))
            return out
        replies = await self.loop.run_in_executor(None, blocking)
        if self.reply_filter is not None:
            replies = await self.reply_filter(replies)
        return replies

    def close(self) -> None:
        self.closed = True


async def pump(queue: asyncio.Queue, handle: Callable[[Inbound], None]) -> None:
    """Hand every inbound message to ``handle`` on the event loop, forever (cancel to stop)."""
    while True:
        handle(await queue.get())


def teardown(bridge: Bridge, declared: list[Any], session: zenoh.Session) -> None:
    """Stop callbacks, undeclare in reverse order, close the session: a process then exits cleanly."""
    bridge.close()
    for d in reversed(declared):
        try:
            d.undeclare()
        except Exception:  # already gone with a lost router: nothing left to release
            pass
    session.close()
