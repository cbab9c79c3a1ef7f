"""The start of a world's clock, heard on Zenoh: the one way anyone learns it.

The world holds a liveliness token (:attr:`zswarm.net.keys.Keys.world_started`) from the start of its
clock to its end. A launcher times its chaos (``--kill K@T``, restarts, outages) from it, whether the
world runs beside it or on another machine, and the benchmarks open their measuring windows on it.
"""

from __future__ import annotations

import threading
from pathlib import Path

import zenoh

from zswarm.net.config import open_session, zenoh_config
from zswarm.net.keys import Keys


class WorldWatch:
    """A client session that waits for the world's token; ``started`` is set once it is heard (at
    once, if the world had started before)."""

    def __init__(self, keys: Keys, endpoint: str, config: Path | None = None, retry_for: float = 15.0,
                 tick_dt: float | None = None) -> None:
        """``tick_dt``: also follow a lockstep world's ticks, each ``tick_dt`` seconds of the run's clock
        (:attr:`run_t`; such a world runs as fast as its agents answer)."""
        self.started = threading.Event()
        self.run_t, self.tick_dt = 0.0, tick_dt  # the run's clock at the last tick heard (``tick_dt`` only)
        self.session = open_session(zenoh_config("client", [endpoint], config=config), retry_for=retry_for)
        self.ticks = self.session.declare_subscriber(keys.tick, self._tick) if tick_dt else None

        def heard(sample: zenoh.Sample) -> None:  # on a Zenoh thread: only sets an event
            if sample.kind == zenoh.SampleKind.PUT:
                self.started.set()

        self.subscriber = self.session.liveliness().declare_subscriber(keys.world_started, history=True,
                                                                       handler=heard)

    def _tick(self, sample: zenoh.Sample) -> None:
        from zswarm.net import messages as msg

        try:
            tick = msg.decode(sample.payload.to_bytes())
        except msg.DecodeError:
            return
        if isinstance(tick, msg.Tick):
            self.run_t = max(self.run_t, tick.step * self.tick_dt)

    def positions(self, key: str, timeout: float = 2.0):
        """Where the world last saw each live agent: (t, ids, positions), or None when it did not answer
        (:class:`zswarm.net.messages.DecodeError` for an answer that does not decode)."""
        from zswarm.net.bridge import ASK_QOS
        from zswarm.net.messages import decode_positions

        for reply in self.session.get(key, timeout=timeout, **ASK_QOS):
            if reply.ok is not None:
                return decode_positions(reply.ok.payload.to_bytes())
        return None

    def close(self) -> None:
        try:
            self.subscriber.undeclare()
            if self.ticks is not None:
                self.ticks.undeclare()
        finally:
            self.session.close()

    def __enter__(self) -> "WorldWatch":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def wait_for_start(keys: Keys, endpoint: str, timeout: float = 180.0) -> None:
    """Return once the world's clock has started (heard on Zenoh through ``endpoint``); a
    :class:`RuntimeError` if it did not within ``timeout`` seconds (the benchmarks' measuring windows)."""
    with WorldWatch(keys, endpoint) as watch:
        if not watch.started.wait(timeout):
            raise RuntimeError(f"the world's clock did not start within {timeout:g} s")
