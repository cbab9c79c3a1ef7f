"""An agent moving between processes (between nodes of a cluster), make-before-break: the process that
takes over (``--takeover``) declares the agent's liveliness token, asks the running one for its state
(body, pose sequence number, counters; not the neighbour table) and says it has it, upon which the
running one leaves (docs/cluster.md, "Placement: agents that move with the swarm")."""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any, Callable

import msgpack

from agents.counters import Counters
from agents.sensing import Body
from zswarm.net.bridge import ASK_QOS

#: Counters fields carried as they are (the rejections are carried as their counts).
_CARRIED = tuple(f.name for f in dataclasses.fields(Counters) if f.name != "rejections")
_BODY = tuple(f.name for f in dataclasses.fields(Body))


def encode_state(body: Body, seq: int, counters: Counters) -> bytes:
    """What a process hands to the one that takes over its agent."""
    return msgpack.packb({"k": "handoff", "body": {name: getattr(body, name) for name in _BODY}, "seq": seq,
                          "counters": {name: getattr(counters, name) for name in _CARRIED},
                          "rejected": dict(counters.rejections.counts)}, use_bin_type=True)


class HandoffError(ValueError):
    pass


def apply_state(payload: bytes, body: Body, counters: Counters) -> int:
    """Set ``body`` and ``counters`` to the handed-over state; returns the pose sequence number to go on
    from. A state of the wrong shape raises :class:`HandoffError` (nothing is changed then)."""
    try:
        state = msgpack.unpackb(payload, raw=False, strict_map_key=False)
        if not isinstance(state, dict) or state.get("k") != "handoff":
            raise HandoffError("not a handoff state")
        new_body = Body(**{name: state["body"][name] for name in _BODY})
        if (new_body.z is None) != (body.z is None):
            raise HandoffError(f"a {new_body.dims}-D state for a {body.dims}-D agent")
        numbers = [new_body.x, new_body.y, new_body.vx, new_body.vy,
                   *(v for v in (new_body.heading, new_body.z, new_body.vz) if v is not None)]
        if not all(type(v) is float and math.isfinite(v) for v in numbers) or type(new_body.step) is not int:
            raise HandoffError("a handoff state whose body is not finite numbers")
        carried = {name: state["counters"][name] for name in _CARRIED}
        defaults = Counters(counters.rejections)
        for name, value in carried.items():  # each counter of its own kind: a number, or a table of numbers
            kind = type(getattr(defaults, name))
            if not (type(value) is kind or (kind is float and type(value) is int)) or (
                    kind is dict and not all(type(k) is int and type(v) in (int, float) for k, v in value.items())):
                raise HandoffError(f"a handoff state whose counter {name!r} is {type(value).__name__}")
        rejected = {str(k): int(v) for k, v in state["rejected"].items()}
        seq = int(state["seq"])
    except HandoffError:
        raise
    except Exception as exc:  # noqa: BLE001 (any malformed state is refused in one line)
        raise HandoffError(f"a malformed handoff state ({type(exc).__name__}: {exc})") from None
    for name in _BODY:
        setattr(body, name, getattr(new_body, name))
    for name, value in carried.items():
        setattr(counters, name, value)
    counters.rejections.counts.update(rejected)
    return seq


#: How long a process that handed its agent over keeps answering with the same state, for a taker
#: whose first answer was lost (it asked again), until the taker says it has it.
LINGER_S = 5.0


class Desk:
    """The running process's side: a queryable on ``keys.handoff(id)``. A query is held (on a Zenoh
    thread) until the agent's loop answers it with its state after a tick (:meth:`answer`); a newer
    one replaces it (the taker asks again when an answer is late: the newest is the one it waits on).
    ``?taken`` is the taker saying it has the state."""

    def __init__(self, session: Any, key: str) -> None:
        self.lock = threading.Lock()
        self.query: Any = None
        self.key = key
        self.taken = threading.Event()
        self.queryable = session.declare_queryable(key, self._held)

    def _held(self, query: Any) -> None:
        if "taken" in str(query.parameters):
            self.taken.set()
            query.drop()
            return
        with self.lock:
            old, self.query = self.query, query
        if old is not None:
            old.drop()  # no answer: its asker has given up on it

    @property
    def due(self) -> bool:
        return self.query is not None

    def answer(self, state: bytes) -> None:
        with self.lock:
            query, self.query = self.query, None
        if query is not None:
            query.reply(self.key, state)
            query.drop()

    def hand_over(self, state: bytes, stopped: Callable[[], bool] = lambda: False, linger: float = LINGER_S) -> bool:
        """Answer with ``state`` (the agent no longer moves) until the taker says it has it; False if it
        did not within ``linger`` seconds or ``stopped()`` (the taker then has it, or never will: either
        way this process is done)."""
        deadline = time.monotonic() + linger
        while not self.taken.is_set() and time.monotonic() < deadline and not stopped():
            if self.due:
                self.answer(state)
            self.taken.wait(0.01)
        return self.taken.is_set()

    def undeclare(self) -> None:
        self.queryable.undeclare()


def take_over(session: Any, key: str, timeout: float, stopped: Callable[[], bool],
              idle: Callable[[], Any] = lambda: None) -> bytes | None:
    """The new process's side: ask for the state until the running process answers (None: nobody did
    within ``timeout`` seconds, or ``stopped()``); ``idle`` runs between asks (take in what arrived)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not stopped():
        for reply in session.get(key, timeout=min(5.0, max(deadline - time.monotonic(), 0.1)), **ASK_QOS):
            if reply.ok is not None:
                state = reply.ok.payload.to_bytes()
                for _ in session.get(f"{key}?taken", timeout=1.0, **ASK_QOS):  # the running process may go now
                    pass
                return state
        idle()
        time.sleep(0.05)
    return None
