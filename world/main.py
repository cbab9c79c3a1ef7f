"""``python -m world``: host obstacles and prey, observe the swarm, record the run."""

from __future__ import annotations

import argparse
import asyncio
import json
import signal
import sys
import time
from pathlib import Path
from typing import Sequence

from world.recorder import WorldRecorder
from world.intake import BATCH_FROM
from world.world import HOLD_MAX_S, World
from zswarm.args import Parser, UsageError, id_ranges, positive_seconds, run_main, seconds
from zswarm.files import check_run_files
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge, teardown
from zswarm.net.config import add_zenoh_args, config_from_args, connected, open_session
from zswarm.net.runspec import RunSpec, add_run_args, spec_from_args
from zswarm.record.live import Viewer, add_viewer_args, viewer_from_args


#: At the end the world waits for each agent's final report: while one that has not reported is alive (it
#: puts its report until the world says it holds it) or the world is cut off from its router (it comes
#: back), else FINAL_STATS_WAIT after the last came or went, FINAL_STATS_MAX in all. Every
#: FINAL_TICK_REPEAT it asks again: the final tick, to the agents still to report.
FINAL_TICK_REPEAT = 0.25
FINAL_STATS_WAIT = 3.0
FINAL_STATS_MAX = 15.0


def build_parser() -> Parser:
    parser = Parser(prog="zswarm world", description="The zswarm world: obstacles, prey, recording, metrics.")
    add_run_args(parser)
    parser.add_argument("--record", type=Path, metavar="FILE.rrd", help="write a Rerun recording")
    parser.add_argument("--summary", type=Path, metavar="FILE.json", help="write the run summary here")
    parser.add_argument("--trajectory", type=Path, metavar="FILE.npz",
                        help="also save the observed positions per step (numpy .npz)")
    parser.add_argument("--start-timeout", type=seconds, default=30.0,
                        help="wait this long for all agents to be alive before starting (default 30 s)")
    parser.add_argument("--step-timeout", type=seconds, default=5.0,
                        help="lockstep: longest wait for the poses of a step (default 5 s)")
    parser.add_argument("--hold-at", type=lambda t: sorted(float(x) for x in t.split(",")), default=[],
                        metavar="T,...", help="lockstep: hold the clock at these run times until SIGUSR1 says the "
                        f"fault due there is staged (at most {HOLD_MAX_S:g} s; the launcher sets it)")
    parser.add_argument("--resume", action="store_true",
                        help="this world replaces one that died: keep --record (and its segments) as it is, "
                             "recover the run so far from it and record the rest into the next segment "
                             "(RECORD.segN.rrd); free clock only")
    parser.add_argument("--progress", type=float, default=2.0, help="seconds between progress lines (0: none)")
    parser.add_argument("--end-after-capture", type=positive_seconds, default=None, metavar="S",
                        help="end the run S simulated seconds after the prey is caught (default: at --duration)")
    parser.add_argument("--sensing-graph", choices=("auto", "on", "off"), default="auto",
                        help="draw who senses whom in the recording's map (auto: for N <= 100)")
    parser.add_argument("--intake", choices=("auto", "batch", "pose"), default="auto",
                        help="free clock: take a tick's poses in at once, as arrays (batch), or one at a time "
                             f"(pose); auto: batch from N = {BATCH_FROM} (below it, one at a time costs less)")
    parser.add_argument("--design", metavar="JSON", type=design_verdict,
                        help="the run's design verdict as its launcher judged it (zswarm run and launch.py pass "
                             "it on, the same check done once); without it the world judges the set itself")
    add_viewer_args(parser)
    add_zenoh_args(parser)
    return parser


def design_verdict(text: str) -> dict:
    """``--design``: a verdict as :func:`zswarm.design.guidelines.verdict` gives it, in JSON."""
    try:
        given = json.loads(text)
    except ValueError:
        given = None
    if not isinstance(given, dict) or "ok" not in given:
        raise argparse.ArgumentTypeError(f"expects a design verdict in JSON (an object with \"ok\"), got {text[:60]!r}")
    return given


async def run_world(args: argparse.Namespace, spec: RunSpec, viewer: Viewer | None = None) -> dict:
    loop = asyncio.get_running_loop()
    session = open_session(config_from_args(args), retry_for=args.connect_timeout)
    recorder = WorldRecorder(args.record, args.summary, args.trajectory, spec.scenario.n_agents, spec.scenario.dt,
                             viewer, {"auto": None, "on": True, "off": False}[args.sensing_graph])
    batched = spec.clock == "free" and (args.intake == "batch" or
                                        (args.intake == "auto" and spec.scenario.n_agents >= BATCH_FROM))
    world = World(spec, session, recorder, list(sys.argv), batched=batched, end_after_capture=args.end_after_capture)
    # free clock: what arrived waits in channels taken out at each world tick; lockstep: each pose wakes
    # the loop (the world waits for the poses of a step)
    bridge = Bridge(session, loop, world.handle, channels=spec.clock == "free",
                    batches={"pose": world.take_poses} if batched else None)
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, world.stop.set)
    loop.add_signal_handler(signal.SIGUSR1, world.go.set)
    keys = spec.keys
    declared = []
    try:
        world.open(args.resume)
        if world.resumed is None:  # a world that resumes a run joins a swarm under way: it judges at the end
            world.judge_design(args.design)
        declared.append(bridge.queryable(keys.obstacles, world.obstacles.answer))
        declared.append(bridge.queryable(keys.positions, world.answer_positions))
        declared.append(bridge.subscribe_liveliness(keys.all_alive, "alive"))  # drained first: who is alive
        declared.append(bridge.subscribe_liveliness(keys.all_members, "in"))  # which cell each agent is in
        declared.append(bridge.subscribe(keys.all_poses, "pose"))
        declared.append(bridge.subscribe(keys.all_stats, "stats"))

        print(f"world: run {spec.run!r}, scenario {spec.scenario.name}, {spec.scenario.n_agents} agents, "
              f"{spec.clock} clock; waiting for the agents", flush=True)
        await world.wait_for_agents(bridge, min(args.start_timeout, 3.0) if world.resumed else args.start_timeout)
        # on Zenoh, for whoever did not start this process (an agents-only machine times its chaos from it)
        declared.append(session.liveliness().declare_token(keys.world_started))
        print(f"world: started with {len(world.census.alive)} agents alive", flush=True)
        if spec.clock == "lockstep":
            await world.run_lockstep(spec.steps, args.progress, args.step_timeout, args.hold_at)
        else:
            await world.run_free(bridge, spec.steps, args.progress)
        expected = world.census.alive | world.census.cut_off  # a world cut off still waits for those
        world.ending = True
        final = msg.Tick(world.clock.step + 1, time.time(), *map(float, world.prey), final=True)
        world.publish(keys.tick, final)
        await collect_final_reports(world, bridge, expected, lambda: world.publish(keys.tick, final, again=True))
        return world.finish()
    finally:
        teardown(bridge, declared, session)


async def collect_final_reports(world: World, bridge: Bridge, expected: set[int], ask_again) -> None:
    """Wait for the final report of each agent in ``expected`` (:data:`FINAL_STATS_WAIT`), never taking
    an agent's leaving for its report (each report is acknowledged as it arrives: :meth:`World.handle`).
    One still missing at the end is named in the log and the summary, its last periodic stats in its place."""
    loop = asyncio.get_running_loop()
    began = heard_at = again = loop.time()
    left: set[int] = set()  # gone without a report: it may still be on its way
    still = set(expected)

    while True:
        bridge.drain()
        now_still = {i for i in still if not world.stats.final(i)}
        if now_still != still:
            still, heard_at = now_still, loop.time()
        alive = still & world.census.alive
        if still - alive - left:
            left |= still - alive
            heard_at = loop.time()
        if not connected(world.session):  # the agents' tokens went with the world's own link
            if world.stop.is_set():  # stopped, the run torn down: no router is coming back
                break
            heard_at = loop.time()  # cut off: its client session reconnects, the agents' tokens come back
        if (not still or loop.time() > began + FINAL_STATS_MAX
                or (not alive and loop.time() > heard_at + FINAL_STATS_WAIT)):
            break
        if loop.time() >= again:  # an agent that missed the final tick would run on, alone, forever
            ask_again()
            again = loop.time() + FINAL_TICK_REPEAT
        await asyncio.sleep(0.05)
    if still:
        world.event(f"final reports: {len(expected) - len(still)} of {len(expected)} after {loop.time() - began:.1f} s; "
                    f"agents {id_ranges(sorted(still))} sent none: their last periodic stats stand in")


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    spec = spec_from_args(args)
    check_run_files(args.record, args.summary, args.trajectory)
    viewer = viewer_from_args(args)  # an unreachable viewer is a usage error before anything starts
    if args.resume and spec.clock == "lockstep":
        raise UsageError("--resume works with the free clock only (a lockstep run cannot re-issue its ticks)")
    result = asyncio.run(run_world(args, spec, viewer))
    keys = ("capture_time", "collisions", "min_pair_distance", "final_components", "messages_rejected")
    done = {k: result.get(k) for k in keys}
    if "collisions_at_one_time" in result:
        done["collisions_at_one_time"] = result["collisions_at_one_time"]
        closest, least = result.get("closest_at_one_time"), result.get("closest_at_one_time_at_least")
        done["closest_at_one_time"] = closest if closest is not None else f">= {least:g}"  # no pair came that near
    print("world: done " + json.dumps(done), flush=True)
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(_main, argv, prog="zswarm world")


if __name__ == "__main__":
    sys.exit(main())
