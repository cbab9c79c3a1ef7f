"""The one bridge between asyncio and Zenoh.

Zenoh calls back on its own threads. :class:`Bridge` keeps those callbacks tiny: they hand the raw
payload to the event loop with ``loop.call_soon_threadsafe`` and never call back into Zenoh;
blocking ``get`` calls run in the loop's executor.
"""

from __future__ import annotations

import asyncio
import time
from collections import deque
from typing import Any, Callable

import zenoh

from zswarm.net.keys import parse_parameters
from zswarm.net.messages import encoding_of
from zswarm.net.rings import WIDE_CAPACITY

#: Every ask (``get``: of a cell, of obstacles, a migration look, a handoff) and so its answers travel
#: with congestion control ``drop``: an answer to an asker whose link is full is dropped (it asks again)
#: rather than waited on. Zenoh's default for queries, ``block``, made the router stop forwarding
#: everything the answering process sent until that link closed (5 s, ``wait_before_close``): a world
#: that answered a starved agent's obstacle query went silent for 5 s and could lose its own link
#: (docs/reliability.md).
ASK_QOS = {"congestion_control": zenoh.CongestionControl.DROP}

Inbound = tuple[str, str, bytes, bool, float]  # (tag, key, payload, is_delete, local wall time of receipt)
Deliver = Callable[[Inbound], None]
Batch = Callable[[list[str], list[bytes], float], None]  # (keys, payloads, when taken out of the channel)


class Bridge:
    """Zenoh callbacks -> ``deliver`` on the event loop's thread; blocking calls -> the executor.

    Three ways in, chosen per bridge:

    - ``batch=False`` (the world, a lockstep agent): each sample is handed to the loop at once with
      ``loop.call_soon_threadsafe``, which wakes it;
    - ``batch=True`` (a free-running agent): the callback only appends the sample to an inbox, and the
      owner empties it with :meth:`drain` once per control tick. The loop is not woken per sample.
    - ``channels=True`` (the free-running world, which hears every pose, and a free-running agent
      when no delay is injected): no Python callback at all; samples wait in a ring channel per
      subscription, and :meth:`drain` takes them out. A subscription made with ``stamped=True`` still
      goes through a callback into the inbox (``batch=True``), for the arrival times it carries.

    Every sample carries the wall time it arrived (the latency figures stay transport latency), or,
    from a channel, the time it was taken out. ``deliver`` is the process's inbound chain, built before
    the bridge (e.g. fault injector -> sensing) and fixed for its life; ``reply_filter`` passes query
    replies through the same faults. ``capacity``: how many samples a subscription's channel holds
    between two drains before the oldest go (liveliness channels always hold ``WIDE_CAPACITY``).
    ``batches``: with channels, tags whose samples are handed over a channel at a time instead (the
    free-running world takes a tick's poses in one call: :meth:`world.world.World.take_poses`).
    """

    def __init__(self, session: zenoh.Session, loop: asyncio.AbstractEventLoop | None, deliver: Deliver,
                 batch: bool = False, channels: bool = False, capacity: int = WIDE_CAPACITY,
                 reply_filter: Callable[[list[tuple[str, bytes]]], Any] | None = None,
                 batches: dict[str, Batch] | None = None) -> None:
        self.session = session
        self.loop = loop
        self.deliver: Deliver = deliver
        self.batches: dict[str, Batch] = batches or {}
        self.batch = batch
        self.inbox: deque[Inbound] = deque()
        self.channels: list[tuple[str, Any]] | None = [] if channels else None  # (tag, subscriber)
        self.capacity = capacity
        # liveliness channels, taken out after the others: a pose sent just before its sender died
        # must not be taken in after the token's deletion, as if the sender had come back
        self.tokens: list[tuple[str, Any]] = []
        self.reply_filter = reply_filter
        self.closed = False

    def _hand_over(self, tag: str) -> Callable[[Any], None]:
        delete = zenoh.SampleKind.DELETE
        append, now = self.inbox.append, time.time

        def to_inbox(sample: Any) -> None:
            if not self.closed:
                append((tag, str(sample.key_expr), sample.payload.to_bytes(), sample.kind == delete, now()))

        def to_loop(sample: Any) -> None:
            if self.closed:
                return
            item = (tag, str(sample.key_expr), sample.payload.to_bytes(), sample.kind == delete, now())
            try:
                self.loop.call_soon_threadsafe(self.deliver, item)
            except RuntimeError:  # loop closed during shutdown
                pass
        return to_inbox if self.batch else to_loop

    @property
    def pending(self) -> int:
        """Samples in the inbox, not yet taken in: the inbound backlog (batch mode)."""
        return len(self.inbox)

    def drain(self) -> int:
        """Deliver every sample waiting (inbox, then channels in the order subscribed); returns how many."""
        n = 0
        inbox, deliver = self.inbox, self.deliver
        while inbox:
            deliver(inbox.popleft())
            n += 1
        if self.channels:
            now = time.time()
            for tag, sub in self.channels:
                n += self._empty(tag, sub, now)
            for tag, sub in self.tokens:
                n += self._empty(tag, sub, now)
        return n

    def _empty(self, tag: str, sub: Any, now: float) -> int:
        batch = self.batches.get(tag)
        if batch is not None:
            keys, payloads = [], []
            while (sample := sub.try_recv()) is not None:
                keys.append(str(sample.key_expr))
                payloads.append(sample.payload.to_bytes())
            if keys:
                batch(keys, payloads, now)
            return len(keys)
        n, deliver, delete = 0, self.deliver, zenoh.SampleKind.DELETE
        while (sample := sub.try_recv()) is not None:
            deliver((tag, str(sample.key_expr), sample.payload.to_bytes(), sample.kind == delete, now))
            n += 1
        return n

    def unsubscribe(self, sub: Any) -> None:
        """Undeclare ``sub`` (a subscriber or a liveliness subscriber); what waits in its channel is
        delivered first."""
        if self.channels is not None:
            for held in (self.channels, self.tokens):
                for i, (tag, s) in enumerate(held):
                    if s is sub:
                        del held[i]
                        self._empty(tag, s, time.time())
                        break
        sub.undeclare()

    def _handler(self, tag: str, stamped: bool = False, capacity: int | None = None) -> Any:
        if self.channels is not None and not stamped:
            return zenoh.handlers.RingChannel(capacity or self.capacity)
        return self._hand_over(tag)

    def _declared(self, tag: str, sub: Any, stamped: bool = False, token: bool = False) -> Any:
        if self.channels is not None and not stamped:
            (self.tokens if token else self.channels).append((tag, sub))
        return sub

    def subscribe(self, key: str, tag: str, stamped: bool = False, remote: bool = False) -> Any:
        """``stamped``: through a callback, with its arrival time, even when the others use channels.
        ``remote``: only what other sessions publish (not this session's own publications)."""
        origin = zenoh.Locality.REMOTE if remote else None
        return self._declared(tag, self.session.declare_subscriber(key, self._handler(tag, stamped),
                                                                   allowed_origin=origin), stamped)

    def subscribe_liveliness(self, key: str, tag: str, history: bool = True) -> Any:
        """``history``: also the tokens already there (their answers can arrive after a later change of
        the same token: a token then seems present that is gone)."""
        return self._declared(tag, self.session.liveliness().declare_subscriber(
            key, self._handler(tag, capacity=WIDE_CAPACITY), history=history),
                              token=True)

    def queryable(self, key: str, answer: Callable[[dict[str, str]], list[tuple[str, bytes]]]) -> Any:
        """``answer`` runs on a Zenoh thread: it must only read immutable data it was given."""
        def handler(query: Any) -> None:
            try:
                for reply_key, payload in answer(parse_parameters(query.parameters)):
                    query.reply(reply_key, payload, encoding=encoding_of(payload))
            except Exception:  # a bad query must never take the process down
                pass
        return self.session.declare_queryable(key, handler)

    async def get(self, selector: str, timeout: float) -> list[tuple[str, bytes]]:
        def blocking() -> list[tuple[str, bytes]]:
            out = []
            for reply in self.session.get(selector, timeout=timeout, **ASK_QOS):
                if reply.ok is not None:
                    out.append((str(reply.ok.key_expr), reply.ok.payload.to_bytes()))
            return out
        replies = await self.loop.run_in_executor(None, blocking)
        if self.reply_filter is not None:
            replies = await self.reply_filter(replies)
        return replies

    def get_into_inbox(self, selector: str, tag: str, timeout: float,
                       done: Callable[[], None] | None = None) -> None:
        """Send a query and return at once; each reply lands in the inbox as a ``tag`` sample (batch
        mode), to be taken in at a later tick like any other sample. ``done`` runs on a Zenoh thread
        once the query is over (every reply in the inbox, or the timeout passed)."""
        append, now = self.inbox.append, time.time

        def on_reply(reply: Any) -> None:
            if not self.closed and reply.ok is not None:
                append((tag, str(reply.ok.key_expr), reply.ok.payload.to_bytes(), False, now()))
        self.session.get(selector, on_reply if done is None else zenoh.handlers.Callback(on_reply, done),
                         timeout=timeout, **ASK_QOS)

    def tokens_into_inbox(self, key: str, tag: str, timeout: float, unanswered: str | None = None,
                          answered: str | None = None) -> None:
        """Ask which liveliness tokens match ``key`` now and return at once; each one joins the inbox
        as a ``tag`` sample (batch mode). Then ``key`` joins it once more: as an ``unanswered`` sample
        where the query ran out its time with no reply (its router frozen or stalled: an empty answer
        comes at once), else as an ``answered`` one, after every token (where each is given)."""
        append, now, asked, heard = self.inbox.append, time.time, time.monotonic(), []

        def on_reply(reply: Any) -> None:
            if not self.closed and reply.ok is not None:
                heard.append(True)
                append((tag, str(reply.ok.key_expr), b"", False, now()))

        def on_done() -> None:
            if self.closed:
                return
            said = unanswered if not heard and _ran_out(asked, timeout) else answered
            if said is not None:
                append((said, key, b"", False, now()))
        self.session.liveliness().get(key, zenoh.handlers.Callback(on_reply, on_done), timeout=timeout)

    def token_absent_into_inbox(self, key: str, tag: str, timeout: float) -> None:
        """Ask whether anybody holds the liveliness token ``key`` and return at once; if the answer came
        and held no token, a ``tag`` sample (deleted, stamped with the time it was asked) joins the
        inbox. A query that ran out its time with no reply says nothing: its router did not answer."""
        asked, started, held = time.time(), time.monotonic(), []

        def on_reply(reply: Any) -> None:
            if reply.ok is not None:
                held.append(True)

        def on_done() -> None:
            if not self.closed and not held and not _ran_out(started, timeout):
                self.inbox.append((tag, key, b"", True, asked))
        self.session.liveliness().get(key, zenoh.handlers.Callback(on_reply, on_done), timeout=timeout)

    def close(self) -> None:
        self.closed = True


def _ran_out(asked: float, timeout: float) -> bool:
    """A query asked at monotonic time ``asked`` ended by its timeout (an answer, even an empty one,
    comes at once from a router that is running)."""
    return time.monotonic() - asked >= 0.9 * timeout


def teardown(bridge: Bridge, declared: list[Any], session: zenoh.Session) -> None:
    """Stop callbacks, undeclare in reverse order, close the session: a process then exits cleanly."""
    bridge.close()
    for d in reversed(declared):
        try:
            d.undeclare()
        except Exception:  # already gone with a lost router: nothing left to release
            pass
    session.close()
