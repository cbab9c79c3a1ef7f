"""``python -m zswarm.bench.crowd``: one process that stands in for many agents, for the world's benchmark.

``zswarm bench world`` measures what the world costs at N agents without N agent processes (a 2-core
machine cannot hold 1000 of them): crowd processes carry the agents' traffic to the world instead.
Agent i of ``--first .. --first + --count - 1`` holds its liveliness token and publishes a real pose
message (msgpack, as an agent's) into the cell of its spawn position at the run's control rate,
through a declared publisher. It stays at its spawn point and runs no law: the world's work (take in,
check, observe, judge, record) does not depend on how the agents move. The crowd leaves, as agents do,
on the world's final tick, or on SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Sequence

import numpy as np

from zswarm.args import Parser, UsageError, positive_int, run_main
from zswarm.net import messages as msg
from zswarm.net.config import add_zenoh_args, config_from_args, open_session
from zswarm.net.rings import CELL_CAPACITY
from zswarm.net.runspec import add_run_args, spec_from_args
from zswarm.stopping import stop_on_signals


def build_parser() -> Parser:
    parser = Parser(prog="zswarm.bench.crowd", description="One process standing in for many agents.")
    parser.add_argument("--first", type=int, default=0, help="the first agent id it stands in for")
    parser.add_argument("--count", type=positive_int, required=True, help="how many agents, from --first")
    add_run_args(parser)
    add_zenoh_args(parser)
    return parser


def run_crowd(args: argparse.Namespace) -> int:
    import zenoh

    spec = spec_from_args(args)
    keys, n = spec.keys, spec.scenario.n_agents
    ids = range(args.first, args.first + args.count)
    if args.first < 0 or ids[-1] >= n:
        raise UsageError(f"--first {args.first} --count {args.count} reaches beyond the run's {n} agents")
    spawn = spec.scenario.initial_positions(np.random.default_rng(spec.seed))
    stop = stop_on_signals()
    session = open_session(config_from_args(args), what=f"crowd {args.first}", retry_for=args.connect_timeout)
    declared: list = []
    try:
        ticks = session.declare_subscriber(keys.tick, zenoh.handlers.RingChannel(CELL_CAPACITY))
        declared.append(ticks)
        agents = []
        for i in ids:
            point = tuple(float(c) for c in spawn[i])
            declared.append(session.liveliness().declare_token(keys.alive(i)))
            publisher = session.declare_publisher(keys.pose(keys.cell(*point), i), encoding=msg.POSE_ENCODING)
            declared.append(publisher)
            agents.append((i, point, publisher))
        z = len(spawn[0]) == 3
        seq, final = 0, False
        next_tick = time.monotonic()
        while not stop.is_set() and not final:
            while (sample := ticks.try_recv()) is not None:
                try:
                    tick = msg.decode(sample.payload.to_bytes())
                except msg.DecodeError:
                    continue
                final = final or (isinstance(tick, msg.Tick) and tick.final)
            seq += 1
            stamp = time.time()
            for i, p, publisher in agents:
                publisher.put(msg.encode_pose(i, seq, stamp, -1, p[0], p[1], 0.0, 0.0, None,
                                              p[2] if z else None, 0.0 if z else None))
            next_tick += spec.period
            time.sleep(max(next_tick - time.monotonic(), 0.0))
    finally:
        for d in reversed(declared):
            d.undeclare()
        session.close()
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(lambda a: run_crowd(build_parser().parse_args(a)), argv, prog="zswarm.bench.crowd")


if __name__ == "__main__":
    sys.exit(main())
