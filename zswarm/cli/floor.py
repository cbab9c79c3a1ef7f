"""``python -m zswarm.cli.floor``: a bare Zenoh process with an agent's traffic and nothing else.

The floor of ``zswarm bench net --floor``: what the middleware alone costs for one agent's traffic.
Like agent ``--id`` of the same run, it holds a liveliness token, subscribes to the cells within
R + 2 v_max dt of the agent's spawn position, and publishes a real pose message (msgpack, about 60
bytes) into its cell at the agent's rate through a declared publisher. It decodes nothing, runs no
control law and no event loop: samples wait in a ring channel that is emptied once per tick.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from typing import Sequence

import numpy as np

from zswarm.args import Parser, run_main
from zswarm.net import messages as msg
from zswarm.net.config import add_zenoh_args, config_from_args, open_session
from zswarm.net.keys import cells_in_disc
from zswarm.net.runspec import add_run_args, spec_from_args


def build_parser() -> Parser:
    parser = Parser(prog="zswarm.cli.floor", description="A bare Zenoh process with one agent's traffic.")
    parser.add_argument("--id", type=int, required=True, help="the agent whose traffic it carries")
    add_run_args(parser)
    add_zenoh_args(parser)
    return parser


def run_floor(args: argparse.Namespace) -> int:
    import zenoh

    spec = spec_from_args(args)
    scenario, keys = spec.scenario, spec.keys
    x, y = map(float, scenario.initial_positions(np.random.default_rng(spec.seed))[args.id])
    reach = scenario.params.swarm.sensing_radius + 2.0 * scenario.params.swarm.v_max * scenario.dt
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(True))
    session = open_session(config_from_args(args), what=f"floor {args.id}", retry_for=args.connect_timeout)
    try:
        token = session.liveliness().declare_token(keys.alive(args.id))
        subs = [session.declare_subscriber(keys.cell_poses(c), zenoh.handlers.RingChannel(256))
                for c in cells_in_disc(keys, x, y, reach)]
        publisher = session.declare_publisher(keys.pose(keys.cell(x, y), args.id))
        seq, received = 0, 0
        next_tick = time.monotonic()
        while not stop:
            for sub in subs:
                while sub.try_recv() is not None:
                    received += 1
            seq += 1
            publisher.put(msg.encode(msg.Pose(args.id, seq, time.time(), -1, x, y, 0.0, 0.0)))
            next_tick += spec.period
            time.sleep(max(next_tick - time.monotonic(), 0.0))
        for d in (publisher, *subs, token):
            d.undeclare()
    finally:
        session.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(lambda a: run_floor(build_parser().parse_args(a)), argv, prog="zswarm.cli.floor")


if __name__ == "__main__":
    sys.exit(main())
