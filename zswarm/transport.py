"""Zenoh: configuration from the standard arguments, every key expression, and the one asyncio bridge.

Key space of a run (``RUN`` is the run id, cells are ``floor(x/size)``, ``floor(y/size)``):

    zswarm/RUN/pose/CX/CY/ID   agent ID's pose, published into the cell it is in; each agent also
                               answers a queryable there with its latest pose
    zswarm/RUN/alive/ID        liveliness token of agent ID
    zswarm/RUN/prey            the prey's position (published by the world)
    zswarm/RUN/tick            lockstep ticks (published by the world)
    zswarm/RUN/obstacles       the world's queryable: ``?x=..;y=..;r=..`` answers obstacles within r
    zswarm/RUN/stats/ID        agent ID's transport counters (for the world's summary)
    zswarm/RUN/control         run control (end of run)

Zenoh calls back on its own threads. :class:`Bridge` keeps those callbacks tiny: they hand the raw
payload to the event loop with ``loop.call_soon_threadsafe`` and never call back into Zenoh;
blocking ``get`` calls run in the loop's executor.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable

import zenoh

from zswarm.cli_util import UsageError

RUN_ID = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")


# --- configuration -------------------------------------------------------------------------------------

def add_zenoh_args(parser: argparse.ArgumentParser, default_mode: str = "client") -> None:
    """The standard Zenoh arguments of the zenoh-python examples."""
    group = parser.add_argument_group("zenoh")
    group.add_argument("--mode", choices=("peer", "client", "router"), default=None,
                       help=f"zenoh session mode (default: the --config file's, else {default_mode})")
    group.add_argument("--connect", "-e", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    group.add_argument("--listen", "-l", action="append", default=[], metavar="ENDPOINT",
                       help="endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    group.add_argument("--config", "-c", type=Path, metavar="FILE",
                       help="a full zenoh configuration file (json5), e.g. one written by 'zswarm certs' "
                            "for TLS and access control; the other flags override it")
    parser.set_defaults(default_mode=default_mode)
    group.add_argument("--scout", action="store_true",
                       help="enable multicast scouting (off by default so runs never meet by accident)")
    group.add_argument("--connect-timeout", type=float, default=15.0, metavar="S",
                       help="keep trying to reach the router this long at start (default 15 s)")


def zenoh_config(mode: str | None = "client", connect: Iterable[str] = (), listen: Iterable[str] = (),
                 config: Path | None = None, scout: bool = False) -> zenoh.Config:
    """A session configuration: the file ``config`` (if any), then the flags over it. ``mode=None``
    keeps the file's mode."""
    if config is not None:
        if Path(config).is_dir():
            raise UsageError(f"cannot read zenoh config {config}: it is a directory; give a .json5 file")
        if not Path(config).is_file():
            raise UsageError(f"zenoh config file {config} does not exist")
        try:
            conf = zenoh.Config.from_file(str(config))
        except Exception as exc:  # zenoh reports parse errors as ZError
            raise UsageError(f"cannot read zenoh config {config}: {_first_line(exc)}") from None
    else:
        conf = zenoh.Config()
    if mode is not None or config is None:
        conf.insert_json5("mode", json.dumps(mode or "client"))
    connect, listen = list(connect), list(listen)
    if connect:
        conf.insert_json5("connect/endpoints", json.dumps(connect))
    if listen:
        conf.insert_json5("listen/endpoints", json.dumps(listen))
    if config is None or scout:
        conf.insert_json5("scouting/multicast/enabled", json.dumps(bool(scout)))
    return conf


DEFAULT_ROUTER = "tcp/127.0.0.1:7447"


def _first_line(exc: Exception) -> str:
    """A zenoh error without the Rust source location it carries."""
    return (str(exc).splitlines() or [""])[0].split(" at /")[0].split(" at ")[0].strip()


def config_from_args(args: argparse.Namespace) -> zenoh.Config:
    """A client with nothing to connect to joins the default local router."""
    connect = args.connect
    mode = args.mode or (None if args.config is not None else args.default_mode)
    if mode == "client" and not connect and args.config is None and not args.scout:
        connect = [DEFAULT_ROUTER]
    return zenoh_config(mode, connect, args.listen, args.config, args.scout)


# One tokio worker for Zenoh's own tasks, instead of a pool per runtime: a swarm runs tens of
# processes on few cores, and idle worker pools only compete for them. Measured with
# `zswarm bench net --agents 50` on 2 cores, three runs each: p99 latency 56-64 ms instead of
# 133-208 ms, 99.3 % of ticks on time instead of 97.7 %, for a higher median (14-17 ms, not 8-11);
# no change at N = 10. Set ZENOH_RUNTIME yourself to override.
LEAN_RUNTIME = ("(app: (worker_threads: 1), acc: (handover: app), tx: (handover: app), "
                "rx: (handover: app), net: (handover: app))")


def open_session(conf: zenoh.Config, what: str = "zenoh", retry_for: float = 0.0) -> zenoh.Session:
    """Open a session, retrying for ``retry_for`` seconds (a router that is still starting); then an
    unreachable router or a taken port is a one-line :class:`UsageError`. Zenoh's runtime is the
    lean one (:data:`LEAN_RUNTIME`) unless ``ZENOH_RUNTIME`` says otherwise."""
    import os
    import time

    os.environ.setdefault("ZENOH_RUNTIME", LEAN_RUNTIME)

    deadline = time.monotonic() + retry_for
    while True:
        try:
            return zenoh.open(conf)
        except Exception as exc:
            first = _first_line(exc)
            if "listener" in first or "in use" in first:
                raise UsageError(f"{what}: cannot listen: {first} (the port is taken or the address is not "
                                 f"local: pick another --listen)") from None
            if time.monotonic() >= deadline:
                waited = f" after {retry_for:g} s" if retry_for > 0 else ""
                raise UsageError(f"{what}: cannot open a zenoh session{waited}: {first} (is the router running "
                                 f"and reachable? check --connect/--listen)") from None
            time.sleep(0.25)


def check_run_id(run: str) -> str:
    if not RUN_ID.match(run):
        raise UsageError(f"run id {run!r} must be 1-64 letters, digits, '_', '.' or '-'")
    return run


# --- keys ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Keys:
    """Every key expression of one run."""

    run: str
    cell_size: float

    @property
    def root(self) -> str:
        return f"zswarm/{self.run}"

    def cell(self, x: float, y: float) -> tuple[int, int]:
        return math.floor(x / self.cell_size), math.floor(y / self.cell_size)

    def pose(self, cell: tuple[int, int], agent: int) -> str:
        return f"{self.root}/pose/{cell[0]}/{cell[1]}/{agent}"

    def any_cell_pose(self, agent: int) -> str:
        """Agent ``agent``'s pose in whichever cell it is (a pattern)."""
        return f"{self.root}/pose/*/*/{agent}"

    def cell_poses(self, cell: tuple[int, int]) -> str:
        return f"{self.root}/pose/{cell[0]}/{cell[1]}/*"

    @property
    def all_poses(self) -> str:
        return f"{self.root}/pose/**"

    def alive(self, agent: int) -> str:
        return f"{self.root}/alive/{agent}"

    @property
    def all_alive(self) -> str:
        return f"{self.root}/alive/*"

    @property
    def prey(self) -> str:
        return f"{self.root}/prey"

    @property
    def tick(self) -> str:
        return f"{self.root}/tick"

    @property
    def obstacles(self) -> str:
        return f"{self.root}/obstacles"

    def obstacle_query(self, x: float, y: float, r: float) -> str:
        return f"{self.obstacles}?x={x!r};y={y!r};r={r!r}"

    def stats(self, agent: int) -> str:
        return f"{self.root}/stats/{agent}"

    @property
    def all_stats(self) -> str:
        return f"{self.root}/stats/*"

    @property
    def control(self) -> str:
        return f"{self.root}/control"

    @staticmethod
    def agent_of(key: str) -> int | None:
        """The agent id at the end of a pose, alive or stats key (None if it is not a number)."""
        tail = key.rsplit("/", 1)[-1]
        return int(tail) if tail.isdigit() else None


def cells_in_disc(keys: Keys, x: float, y: float, r: float) -> set[tuple[int, int]]:
    """Every cell whose square meets the disc of radius r about (x, y)."""
    s = keys.cell_size
    out = set()
    for cx in range(math.floor((x - r) / s), math.floor((x + r) / s) + 1):
        for cy in range(math.floor((y - r) / s), math.floor((y + r) / s) + 1):
            nx = min(max(x, cx * s), (cx + 1) * s)
            ny = min(max(y, cy * s), (cy + 1) * s)
            if (nx - x) ** 2 + (ny - y) ** 2 <= r * r:
                out.add((cx, cy))
    return out


def parse_parameters(text: str) -> dict[str, str]:
    """``x=1.0;y=2.0;r=1.5`` -> {'x': '1.0', ...}."""
    out = {}
    for part in str(text).split(";"):
        name, sep, value = part.partition("=")
        if sep:
            out[name.strip()] = value.strip()
    return out


# --- the asyncio bridge --------------------------------------------------------------------------------

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
