"""``python -m agents``: start one agent process (see :mod:`agents.agent`)."""

from __future__ import annotations

import asyncio
import signal
import sys
from typing import Sequence

import numpy as np

from agents.agent import Agent
from zswarm.args import Parser, UsageError, run_main
from zswarm.net.bridge import Bridge, pump, teardown
from zswarm.net.config import add_zenoh_args, config_from_args, open_session
from zswarm.net.injector import FaultInjector
from zswarm.net.runspec import RunSpec, add_run_args, spec_from_args


def build_parser() -> Parser:
    parser = Parser(prog="agents", description="One zswarm agent: an independent asyncio process that "
                    "senses its neighbours over Zenoh and follows the APF control law.")
    parser.add_argument("--id", type=int, required=True, help="this agent's id (0 .. N-1 for spawn)")
    parser.add_argument("--start", metavar="X,Y", help="start position (default: the scenario's spawn "
                        "for this id and seed)")
    parser.add_argument("--staleness", type=float, default=0.5,
                        help="free clock: ignore neighbour data older than this many seconds (default 0.5)")
    parser.add_argument("--lockstep-wait", type=float, default=0.25,
                        help="lockstep: wait this long for expected poses of a step before asking the "
                             "cells for them (default 0.25 s)")
    parser.add_argument("--start-timeout", type=float, default=60.0,
                        help="give up if the world has not answered for this long at start (default 60 s: "
                             "a world on a loaded machine, or started later elsewhere, may take a while)")
    add_run_args(parser)
    add_zenoh_args(parser)
    return parser


def start_position(spec: RunSpec, agent_id: int, text: str | None) -> np.ndarray:
    if text is not None:
        try:
            x, y = (float(v) for v in text.split(","))
        except ValueError:
            raise UsageError(f"--start expects X,Y (got {text!r})") from None
        return np.array([x, y])
    spawn = spec.scenario.initial_positions(np.random.default_rng(spec.seed))
    if not 0 <= agent_id < len(spawn):
        raise UsageError(f"--id {agent_id} has no spawn position in {spec.scenario.name} "
                         f"(N = {len(spawn)}); give --start X,Y or an id below {len(spawn)}")
    return spawn[agent_id]


async def run_agent(spec: RunSpec, args) -> int:
    loop = asyncio.get_running_loop()
    start = start_position(spec, args.id, args.start)
    session = open_session(config_from_args(args), what=f"agent {args.id}", retry_for=args.connect_timeout)
    queue: asyncio.Queue = asyncio.Queue()
    bridge = Bridge(session, loop, queue)
    agent = Agent(spec, args.id, bridge, start, args.staleness, args.lockstep_wait)
    if spec.faults.active:
        injector = FaultInjector(spec.faults, args.id, loop, queue.put_nowait, agent.sensing.fault_source)
        bridge.deliver, bridge.reply_filter = injector.deliver, injector.filter_replies
        agent.injector = injector
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, agent.stop.set)
    keys = spec.keys
    declared = []
    try:
        declared.append(bridge.subscribe_liveliness(keys.all_alive, "alive"))
        declared.append(bridge.subscribe(keys.prey, "prey"))
        declared.append(bridge.subscribe(keys.tick, "tick"))

        pump_task = asyncio.ensure_future(pump(queue, agent.sensing.handle))
        deadline = loop.time() + args.start_timeout
        while not await agent.sensing.refresh_obstacles(timeout=1.0):
            if loop.time() > deadline or agent.stop.is_set():
                raise UsageError(f"agent {args.id}: the world of run {spec.run!r} did not answer for "
                                 f"{args.start_timeout:g} s (start the world, or check --run/--connect)")
        await agent.sensing.update_cells()
        declared.append(session.liveliness().declare_token(keys.alive(args.id)))
        stats_task = asyncio.ensure_future(agent.publish_stats())
        if spec.clock == "lockstep":
            await agent.run_lockstep()
        else:
            async def end_on_final_tick() -> None:
                while not agent.stop.is_set():
                    if (await agent.sensing.ticks.get()).final:
                        agent.stop.set()
            end_task = asyncio.ensure_future(end_on_final_tick())
            await agent.run_free()
            end_task.cancel()
        agent.stop.set()
        stats_task.cancel()
        pump_task.cancel()
        session.put(keys.stats(args.id), agent.stats(final=True))
        return 0
    finally:
        teardown(bridge, declared, session)


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    spec = spec_from_args(args)
    if args.id < 0:
        raise UsageError(f"--id must be >= 0 (got {args.id})")
    return asyncio.run(run_agent(spec, args))


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(_main, argv, prog="agents")


if __name__ == "__main__":
    sys.exit(main())
