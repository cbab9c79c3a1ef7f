"""``python -m zswarm.net.router``: a Zenoh router (a Python session in router mode).

No router binary installs from the package registries; a router-mode session routes for every client.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from typing import Sequence

from zswarm.args import Parser, run_main
from zswarm.net.config import add_zenoh_args, config_from_args, open_session
from zswarm.ports import LOOPBACK
from zswarm.stopping import stop_on_signals

ROUTER_RUNTIME: str | None = None  # Zenoh's default pools


def build_parser() -> Parser:
    parser = Parser(prog="zswarm router", description="Run a Zenoh router until SIGINT/SIGTERM.")
    add_zenoh_args(parser, default_mode="router")
    return parser


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    if not args.listen and args.config is None:
        args.listen = [f"tcp/{LOOPBACK}:7447"]
    stop = stop_on_signals()
    # the router is no agent: it carries every message of the swarm, so it keeps Zenoh's own
    # multi-threaded runtime rather than the agents' single worker (measured: docs/benchmarks.md)
    session = open_session(config_from_args(args), runtime=ROUTER_RUNTIME)
    try:
        if args.connect and not joined(session, args.connect_timeout, stop):
            if stop.is_set():
                return 0
            print(f"router: could not join {', '.join(args.connect)} within {args.connect_timeout:g} s: {JOIN_HINT}",
                  file=sys.stderr, flush=True)
            return JOIN_FAILED
        print(f"{READY} {', '.join(args.listen) or 'the config file endpoints'}", flush=True)
        stop.wait()
    finally:
        close_within(session, CLOSE_WAIT_S)
    return 0


#: The router's first line on stdout once it listens (and, with ``--connect``, has joined that router).
READY = "router: listening on"
#: Its exit status when it could not join the router it was told to (``--connect``) in time.
JOIN_FAILED = 2
JOIN_HINT = "nothing answers there, or the two routers' certificates are not from one CA"


def joined(session, seconds: float, stop: threading.Event) -> bool:
    """Whether the session links to another router within ``seconds`` (a TLS router whose certificate the
    other refuses, or that refuses the other's, keeps trying and never does)."""
    deadline = time.monotonic() + seconds
    while not session.info.routers_zid():
        if time.monotonic() > deadline or stop.is_set():
            return False
        time.sleep(0.05)
    return True


#: How long a stopping router waits for its session to close before it leaves without it.
CLOSE_WAIT_S = 2.0


def close_within(session, wait: float) -> None:
    """Close the session, but never wait more than ``wait`` seconds for it: closing waits on clients
    that read late, and on a loaded machine that took over 10 s, during which the router went on
    routing, so a stopped router was not stopped. A router keeps nothing worth the wait: past it, the
    process ends at once (the kernel closes its connections and every client sees the router gone)."""
    closer = threading.Thread(target=session.close, name="router-close", daemon=True)
    closer.start()
    closer.join(wait)
    if closer.is_alive():
        print(f"router: closing took over {wait:g} s; leaving without it", file=sys.stderr, flush=True)
        sys.stdout.flush()
        os._exit(0)


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(_main, argv, prog="zswarm router")


if __name__ == "__main__":
    sys.exit(main())
