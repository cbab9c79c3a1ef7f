"""``python -m zswarm.bench.floor``: a bare Zenoh process with an agent's traffic and nothing else.

The floor of ``zswarm bench net --floor``: what the middleware alone costs for one agent's traffic.
Like agent ``--id`` of the same run, it holds a liveliness token, subscribes to the cells within
R + 2 v_max dt of the agent's spawn position (its own publications not handed back, as an agent's)
and to the prey, and publishes a real pose message
(the 64-byte record of ``zswarm.net.messages``) into its cell at the agent's rate through a declared publisher. It decodes
nothing, runs no control law and no event loop: samples wait in a ring channel emptied once per tick
(``--handler callback``: a Python callback appends each to a list, as an agent's inbox does).
``--prey`` makes it the world's stand-in instead: it only publishes the prey at the same rate.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Sequence

import numpy as np

from zswarm.args import Parser, run_main
from zswarm.net import messages as msg
from zswarm.net.config import add_zenoh_args, config_from_args, open_session
from zswarm.net.keys import cells_in_disc
from zswarm.net.rings import CELL_CAPACITY
from zswarm.net.runspec import add_run_args, spec_from_args
from zswarm.stopping import stop_on_signals


def build_parser() -> Parser:
    parser = Parser(prog="zswarm.bench.floor", description="A bare Zenoh process with one agent's traffic.")
    parser.add_argument("--id", type=int, default=0, help="the agent whose traffic it carries")
    parser.add_argument("--handler", choices=("ring", "callback", "direct"), default="ring",
                        help="how samples reach Python (default ring: a channel drained once per tick)")
    parser.add_argument("--prey", action="store_true", help="publish the prey at the agents' rate, nothing else")
    add_run_args(parser)
    add_zenoh_args(parser)
    return parser


def run_floor(args: argparse.Namespace) -> int:
    import zenoh

    spec = spec_from_args(args)
    scenario, keys = spec.scenario, spec.keys
    x, y = map(float, scenario.initial_positions(np.random.default_rng(spec.seed))[args.id])
    reach = spec.subscription_radius
    stop = stop_on_signals()
    session = open_session(config_from_args(args), what=f"floor {args.id}", retry_for=args.connect_timeout)
    inbox: list = []

    def handler():
        if args.handler == "ring":
            return zenoh.handlers.RingChannel(CELL_CAPACITY)  # as an agent's
        append = lambda sample: inbox.append((str(sample.key_expr), sample.payload.to_bytes(), time.time()))  # noqa: E731
        return zenoh.handlers.Callback(append, indirect=args.handler == "callback")
    try:
        if args.prey:
            declared = [session.declare_publisher(keys.prey, encoding=msg.ENCODING)]
            message = lambda seq: msg.encode(msg.Prey(seq, time.time(), -1, 1000.0, 0.0))  # noqa: E731
        else:
            declared = [session.liveliness().declare_token(keys.alive(args.id)),
                        session.declare_subscriber(keys.prey, handler()),
                        *(session.declare_subscriber(keys.cell_poses(c), handler(),
                                                     allowed_origin=zenoh.Locality.REMOTE)
                          for c in cells_in_disc(keys, (x, y), reach)),
                        session.declare_publisher(keys.pose(keys.cell(x, y), args.id), encoding=msg.POSE_ENCODING)]
            message = lambda seq: msg.encode(msg.Pose(args.id, seq, time.time(), -1, x, y, 0.0, 0.0))  # noqa: E731
        subs = [d for d in declared if hasattr(d, "try_recv") and args.handler == "ring"]
        publisher = declared[-1] if not args.prey else declared[0]
        seq, received = 0, 0
        next_tick = time.monotonic()
        while not stop.is_set():
            for sub in subs:
                while sub.try_recv() is not None:
                    received += 1
            received += len(inbox)
            inbox.clear()
            seq += 1
            publisher.put(message(seq))
            next_tick += spec.period
            time.sleep(max(next_tick - time.monotonic(), 0.0))
        for d in reversed(declared):
            d.undeclare()
    finally:
        session.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(lambda a: run_floor(build_parser().parse_args(a)), argv, prog="zswarm.bench.floor")


if __name__ == "__main__":
    sys.exit(main())
