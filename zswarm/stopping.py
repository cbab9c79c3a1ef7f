"""A stop flag that SIGINT and SIGTERM set, safe however many signals come and however fast.

A ``threading.Event`` set from a signal handler can deadlock: the handler runs in the main thread
between two bytecodes, and when a second signal arrives while the first handler is inside
``Event.set`` (holding the Event's lock), the second handler waits on that lock for ever. A router
hung so, its launcher gone, with three handlers stacked in ``Event.set``. :class:`StopSignal` is a
plain flag: setting it takes no lock, and waiting on it polls.
"""

from __future__ import annotations

import signal
import time

POLL_S = 0.05


class StopSignal:
    """``set``, ``is_set`` and ``wait`` as a ``threading.Event``'s, without a lock."""

    def __init__(self) -> None:
        self._set = False

    def set(self, *_: object) -> None:  # also a signal handler: (signum, frame)
        self._set = True

    def is_set(self) -> bool:
        return self._set

    def wait(self, timeout: float | None = None) -> bool:
        """Until set, or ``timeout`` seconds (None: for ever); returns whether it is set."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while not self._set:
            left = POLL_S if deadline is None else min(POLL_S, deadline - time.monotonic())
            if left <= 0.0:
                break
            time.sleep(left)
        return self._set


def stop_on_signals() -> StopSignal:
    """A :class:`StopSignal` that SIGINT and SIGTERM set (call it in the main thread)."""
    stop = StopSignal()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, stop.set)
    return stop
