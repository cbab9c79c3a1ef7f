"""``python -m agents``: start one agent process (see :mod:`agents.agent`)."""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import signal
import sys
import threading
import time
from array import array
from pathlib import Path
from typing import TYPE_CHECKING, Any, Coroutine, Sequence

import numpy as np
import zenoh

from agents.agent import Agent, starting_body
from agents.free import run_free, take_in, wait_for_world
from agents.handoff import Desk, HandoffError, apply_state, encode_state, take_over
from agents.outreach import Outreach
from agents.sensing import Sensing
from zswarm.args import Parser, UsageError, run_main, seconds
from zswarm.laws.bound import EXIT_LAW_FAILED
from zswarm.control.step import control_step
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge, Deliver, Inbound, teardown
from zswarm.net.config import add_zenoh_args, config_from_args, connected, open_session
from zswarm.net.injector import FaultInjector
from zswarm.net.rings import CELL_CAPACITY
from zswarm.net.runspec import LEASE_S, WORLD_SILENT_S, RunSpec, add_run_args, spec_from_args
from zswarm.stopping import stop_on_signals

#: An agent puts its final report again every FINAL_RESEND_S until the world says it holds it
#: (``keys.report_taken``), the world is gone, or FINAL_REPORT_MAX_S have passed: its silence proves
#: nothing (a router stalled on a congested link delays everything it forwards), only the world's word does.
FINAL_RESEND_S = 0.5
FINAL_REPORT_MAX_S = 14.0

if TYPE_CHECKING:
    from agents.robot_link import RobotLink
    from zswarm.ros.robots import RobotsFile


def build_parser() -> Parser:
    parser = Parser(prog="zswarm agent", description="One zswarm agent: an independent process that senses its "
                    "neighbours over Zenoh and follows the APF control law.")
    parser.add_argument("--id", type=int, required=True, help="this agent's id (0 .. N-1 for spawn)")
    parser.add_argument("--start", metavar="X,Y[,Z]", help="start position (X,Y,Z in a 3-D scenario; default: "
                        "the scenario's spawn for this id and seed)")
    parser.add_argument("--node", type=int, default=0,
                        help="the index of the router (the cluster node) it connects to: its poses carry it, and "
                             "it counts the poses it takes in from another router (default 0)")
    parser.add_argument("--movable", action="store_true",
                        help="answer a process that takes this agent over (zswarm run --migrate-every; free clock)")
    parser.add_argument("--takeover", action="store_true",
                        help="take over the running process of this agent: start from its state (--start: "
                             "about where it is, to enter its cells early), then it leaves (implies --movable)")
    parser.add_argument("--staleness", type=float, default=0.5,
                        help="free clock: ignore neighbour data older than this many seconds (default 0.5)")
    parser.add_argument("--lockstep-wait", type=seconds, default=0.25,
                        help="lockstep: wait this long for expected poses of a step before asking the "
                             "cells for them (default 0.25 s)")
    parser.add_argument("--start-timeout", type=seconds, default=60.0,
                        help="give up if the world has not answered for this long at start (default 60 s: "
                             "a world on a loaded machine, or started later elsewhere, may take a while)")
    parser.add_argument("--robots", type=Path, default=None, metavar="FILE.toml",
                        help="a robots file: if it names this agent's id, a ROS 2 robot is its body (its pose "
                             "from the robot's odometry, its command sent as cmd_vel; docs/robots.md)")
    parser.add_argument("--tracks", type=Path, default=None, metavar="DIR",
                        help="keep every pose this agent sends and write them, when it ends, to "
                             "DIR/agent-ID-PID.npy (rows: stamp, x, y[, z]): the exact record the run's "
                             "collisions are judged from at one instant (zswarm run --tracks)")
    parser.add_argument("--world-timeout", type=seconds, default=WORLD_SILENT_S, metavar="S",
                        help="leave the swarm (exit 1) once nothing has come from the world for S seconds after "
                             "its clock started: it ended or died without a final tick heard here (default "
                             f"{WORLD_SILENT_S:g} s)")
    parser.add_argument("--odom-timeout", type=seconds, default=1.0,
                        help="with a robot: hold it stopped while its odometry has stopped this long, until it "
                             "comes back (default 1 s)")
    parser.add_argument("--odom-lost", type=seconds, default=LEASE_S, metavar="S",
                        help="with a robot: stop it and leave the swarm when its odometry has stopped S seconds "
                             f"(default {LEASE_S:g} s: as long as a pause may be)")
    add_run_args(parser)
    add_zenoh_args(parser)
    return parser


def start_position(spec: RunSpec, agent_id: int, text: str | None) -> tuple[float, ...]:
    dims = spec.scenario.dimensions
    form = "X,Y" if dims == 2 else "X,Y,Z"
    if text is not None:
        try:
            point = tuple(float(v) for v in text.split(","))
        except ValueError:
            point = ()
        if len(point) != dims or not all(math.isfinite(c) for c in point):
            raise UsageError(f"--start expects {form} in {spec.scenario.name} ({dims}-D; got {text!r})")
        return point
    spawn = spec.scenario.initial_positions(np.random.default_rng(spec.seed))
    if not 0 <= agent_id < len(spawn):
        raise UsageError(f"--id {agent_id} has no spawn position in {spec.scenario.name} "
                         f"(N = {len(spawn)}); give --start {form} or an id below {len(spawn)}")
    return tuple(float(c) for c in spawn[agent_id])


def inbound_chain(sensing: Sensing, injector: FaultInjector | None, robot: RobotLink | None) -> Deliver:
    """Where every sample the bridge takes in goes: the robot's odometry to its driver, the rest
    through the fault injector (when faults are injected) into sensing."""
    to_sensing = sensing.handle if injector is None else injector.deliver
    if robot is None:
        return to_sensing

    def deliver(item: Inbound) -> None:
        if item[0] == "odom":
            robot.take(item[2], item[4])
        else:
            to_sensing(item)
    return deliver


class Process:
    """What one agent process holds, built top to bottom in this constructor and never rewired: its
    session, its body, the robot that drives the body (if any), sensing, the fault injector on its
    inbound links (if faults are injected), the bridge that delivers into them, what it asks of the
    network, the agent, and what it declared (undeclared in reverse order at the end)."""

    def __init__(self, spec: RunSpec, args: argparse.Namespace, loop: asyncio.AbstractEventLoop | None,
                 robots: RobotsFile | None = None) -> None:
        start = start_position(spec, args.id, args.start)
        self.spec, self.id = spec, args.id
        p, keys = spec.scenario.params, spec.keys
        # its own control step (zswarm run probed the laws before any process started)
        control = control_step([spec.scenario], [spec.combination], spec.safety, agents=[args.id])
        self.session = open_session(config_from_args(args), retry_for=args.connect_timeout)
        body = starting_body(control, start, spec.scenario.prey_start)
        # free clock: samples wait in ring channels (in an inbox, stamped on arrival, when a delay is
        # injected from the arrival time) and are taken in once per tick; lockstep: each one wakes the loop
        rings = loop is None and not (spec.faults.latency or spec.faults.jitter)
        sensing = Sensing(spec, args.id, body, probe_latency=rings, node=args.node)
        robot = robots.robot(args.id) if robots is not None else None
        link = None
        if robot is not None:
            from agents.robot_link import RobotLink

            link = RobotLink(robot, robots.route, self.session, p.swarm.v_max, p.body.lookahead,
                             sensing.counters.rejections, args.odom_timeout, args.id, args.odom_lost)
        injector = (FaultInjector(spec.faults, args.id, loop, sensing.handle, sensing.fault_source)
                    if spec.faults.active else None)
        self.bridge = Bridge(self.session, loop, inbound_chain(sensing, injector, link), batch=loop is None,
                             channels=rings, capacity=CELL_CAPACITY,
                             reply_filter=injector.filter_replies if injector is not None else None)
        self.tracks: Path | None = args.tracks
        self.agent = Agent(spec, args.id, body, sensing, Outreach(sensing, self.bridge), self.bridge, control, injector,
                           link, args.staleness, args.lockstep_wait, track=array("d") if args.tracks is not None else None)
        self.agent.world_timeout = args.world_timeout
        self.injector = injector
        self.declared = [self.bridge.subscribe_liveliness(keys.all_alive, "alive"),
                         self.bridge.subscribe(keys.prey, "prey"), self.bridge.subscribe(keys.tick, "tick")]
        if link is not None:
            self.declared.append(self.bridge.subscribe(link.odom_key, "odom"))

    def no_world(self, waited: float) -> UsageError:
        """Why it cannot join: the world is of another dimension, or did not answer."""
        foreign, dims = self.agent.sensing.obstacle_view.foreign_dims, self.spec.scenario.dimensions
        robot = self.agent.robot
        if robot is not None and robot.pose is None and self.agent.sensing.obstacle_query_at is not None:
            return UsageError(f"agent {self.id}: no odometry from robot {robot.robot.namespace} for {waited:g} s "
                              f"(is it up, on this router, and on the robots file's route and distro?)")
        if foreign is not None:
            return UsageError(f"agent {self.id}: the world of run {self.spec.run!r} is {foreign}-D and this agent "
                              f"{dims}-D ({self.spec.scenario.name}); start every process of a run with the same "
                              "--scenario")
        return UsageError(f"agent {self.id}: the world of run {self.spec.run!r} did not answer for {waited:g} s "
                          f"(start the world, or check --run/--connect)")

    def announce(self) -> None:
        """Alive: a liveliness token under its id (only agents holding one count as neighbours)."""
        self.declared.append(self.session.liveliness().declare_token(self.spec.keys.alive(self.id)))

    def close(self, final_stats: bool, ended: bool = True) -> None:
        """Leave: the final report (``final_stats``: until the world holds it where the run ``ended``; put
        once where a signal stopped the agent, the run torn down), then the session."""
        if self.agent.robot is not None:
            self.agent.robot.close()  # a zero Twist: a robot is never left driving on the last command
        if final_stats:
            self.final_report(wait=ended)
        teardown(self.bridge, self.declared, self.session)
        if self.tracks is not None and self.agent.track:
            write_track(self.tracks, self.id, self.agent.track, self.spec.scenario.dimensions)

    def final_report(self, wait: bool = True) -> None:
        """The run's totals, put until the world says it holds them (:data:`FINAL_RESEND_S`), or it is
        gone, or :data:`FINAL_REPORT_MAX_S` passed. A put that a congested link drops is put again, so
        none waits for room there (a router waiting on one stalls everything it forwards). Without
        ``wait``, put once."""
        keys, report = self.spec.keys, self.agent.stats(final=True)
        if not wait:
            self.session.put(keys.stats(self.id), report, encoding=msg.ENCODING, express=True)
            return
        taken, gone = threading.Event(), threading.Event()
        ack = self.session.declare_subscriber(keys.report_taken(self.id), lambda sample: taken.set())
        world = self.session.liveliness().declare_subscriber(
            keys.world_started, lambda sample: gone.set() if sample.kind == zenoh.SampleKind.DELETE else None)
        if not any(r.ok is not None for r in self.session.liveliness().get(keys.world_started, timeout=1.0)):
            gone.set()  # no world to report to
        deadline = time.monotonic() + FINAL_REPORT_MAX_S
        while True:
            self.session.put(keys.stats(self.id), report, encoding=msg.ENCODING, express=True)
            if (taken.wait(FINAL_RESEND_S) or gone.is_set() or time.monotonic() > deadline
                    or not connected(self.session)):  # a router gone with the world: nobody to hear it
                break
        world.undeclare()
        ack.undeclare()


def write_track(folder: Path, agent_id: int, track: array, dims: int) -> None:
    """``--tracks``: the poses it sent, as rows (stamp, x, y[, z]), in one file per process."""
    rows = np.frombuffer(track, dtype=float).reshape(-1, 1 + dims)
    np.save(folder / f"agent-{agent_id}-{os.getpid()}.npy", rows)


def preload() -> None:
    """Walk an agent's start short of its session (its arguments, spawn point and control step), then
    import the other built-in laws and uvloop: what an agent would otherwise import after a fleet forks
    it, each agent its own copy (:mod:`agents.fleet`)."""
    from zswarm.laws.registry import BUILTIN, resolve

    spec = spec_from_args(build_parser().parse_args(["--id", "0", "--set", "n_agents=3"]))  # scaled, as runs are
    start_position(spec, 0, None)
    control_step([spec.scenario], [spec.combination], spec.safety, agents=[0])
    for name in BUILTIN:
        resolve(name)
    try:
        import uvloop  # noqa: F401
    except ImportError:
        pass


def run_loop(main: Coroutine[Any, Any, int]) -> int:
    """Run an agent's coroutine on uvloop's event loop where it is installed (the cheaper loop:
    docs/benchmarks.md, "An agent against an earlier version"), else on asyncio's own."""
    try:
        import uvloop
    except ImportError:
        return asyncio.run(main)
    return uvloop.run(main)


def run_free_agent(spec: RunSpec, args: argparse.Namespace, robots: RobotsFile | None = None) -> int:
    """The free clock (:mod:`agents.free`): samples wait in the bridge's channels and inbox, taken in
    once a tick of the loop."""
    # signals stop the run once it has a session; until then (a router still starting: up to
    # --connect-timeout) they end the process at once, as they would any other
    proc = Process(spec, args, loop=None, robots=robots)
    agent = proc.agent
    stopped = stop_on_signals().is_set
    done = moved = False
    owns = not args.takeover  # a taker-over speaks for the agent (its final report) once it has its state
    desk = None

    async def life() -> int:
        nonlocal done, moved, owns, desk
        if not await wait_for_world(agent, proc.injector, args.start_timeout, stopped):
            if stopped():
                return 0
            raise proc.no_world(args.start_timeout)
        proc.announce()  # a taker-over's token beside the running process's: nobody sees the agent leave
        if args.takeover:
            if not take_over_agent(proc, args, stopped):
                return 0
            owns = True
        if args.movable or args.takeover:
            desk = Desk(proc.session, spec.keys.handoff(args.id))
        moved = await run_free(agent, proc.injector, stopped, desk)
        if moved and not desk.hand_over(encode_state(agent.body, agent.seq, agent.counters), stopped):
            # the taker never said it has the state: this process reports for the agent (should the taker
            # have it after all, its report counts more ticks and stands instead: world.report.StatsBook.get)
            moved = False
            if not stopped():
                print(f"agent {args.id}: the process taking it over did not confirm it has its state; this one "
                      "puts the agent's final report", file=sys.stderr, flush=True)
        done = True
        return ending_code(agent)

    try:
        return run_loop(life())
    finally:
        if desk is not None:
            desk.undeclare()
        # a moved agent's counts went with it
        proc.close(final_stats=(done or stopped()) and owns and not moved, ended=done and not stopped())


def take_over_agent(proc: Process, args: argparse.Namespace, stopped) -> bool:
    """``--takeover``: the running process's state, then the cells around where it really is (False:
    stopped while asking)."""
    agent = proc.agent
    state = take_over(proc.session, proc.spec.keys.handoff(args.id), args.start_timeout, stopped,
                      idle=lambda: take_in(agent, proc.injector))
    if state is None:
        if stopped():
            return False
        raise UsageError(f"agent {args.id}: no running process of it answered for {args.start_timeout:g} s "
                         "(--takeover takes over a running agent of the run)")
    try:
        agent.seq = apply_state(state, agent.body, agent.counters)
    except HandoffError as exc:
        raise UsageError(f"agent {args.id}: {exc}") from None
    agent.reach.follow_cells(ask=True)
    return True


async def run_lockstep_agent(spec: RunSpec, args: argparse.Namespace) -> int:
    loop = asyncio.get_running_loop()
    proc = Process(spec, args, loop)
    agent = proc.agent
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, agent.stop.set)
    done = False
    try:
        deadline = loop.time() + args.start_timeout
        while not await agent.reach.refresh_obstacles(timeout=1.0):
            if loop.time() > deadline or agent.stop.is_set() or agent.sensing.obstacle_view.foreign_dims:
                raise proc.no_world(args.start_timeout)
            await asyncio.sleep(0.25)  # no world yet: a query without a queryable fails at once
        await agent.reach.update_cells()
        proc.announce()
        stats_task = asyncio.ensure_future(agent.publish_stats())
        await agent.run_lockstep()
        agent.stop.set()
        stats_task.cancel()
        done = True
        return ending_code(agent)
    finally:
        proc.close(final_stats=done)


def ending_code(agent: Agent) -> int:
    """0, or, after its law failed, one line on stderr (the agent's log) and :data:`EXIT_LAW_FAILED`: the
    launcher counts it as a crash and the other agents carry on; 1, in one line, when its world fell
    silent (``--world-timeout``)."""
    if agent.world_lost:
        print(f"agent {agent.id}: nothing came from the world of run {agent.spec.run!r} for "
              f"{agent.world_timeout:g} s (it ended or died, its final tick unheard here): leaving",
              file=sys.stderr, flush=True)
        return 1
    if agent.law_failure is None:
        return 0
    print(f"agent {agent.id}: {agent.law_failure}; it braked and left the swarm", file=sys.stderr, flush=True)
    return EXIT_LAW_FAILED


def robots_file(args: argparse.Namespace, spec: RunSpec) -> RobotsFile | None:
    """The robots file of ``--robots`` (None without one), checked against the run."""
    if args.robots is None:
        return None
    from zswarm.ros.robots import robots_for_run

    if not 0.0 < args.odom_timeout <= 60.0:
        raise UsageError(f"--odom-timeout must be in (0, 60] s (got {args.odom_timeout})")
    if not args.odom_timeout < args.odom_lost <= 600.0:
        raise UsageError(f"--odom-lost must be above --odom-timeout ({args.odom_timeout:g} s) and at most 600 s "
                         f"(got {args.odom_lost:g})")
    return robots_for_run(args.robots, spec.scenario.name, spec.scenario.dimensions, spec.clock, spec.time_scale)


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    spec = spec_from_args(args)
    robots = robots_file(args, spec)  # a bad robots file stops here, before a session is opened
    if args.id < 0:
        raise UsageError(f"--id must be >= 0 (got {args.id})")
    if not 0 <= args.node <= 0xFFFF:
        raise UsageError(f"--node must be in 0..65535 (got {args.node})")
    if spec.clock == "lockstep":
        if args.movable or args.takeover:
            raise UsageError("--movable/--takeover run on the free clock only (a lockstep step waits for every "
                             "agent's pose of the step)")
        return run_loop(run_lockstep_agent(spec, args))
    return run_free_agent(spec, args, robots)  # robots run on the free clock only (robots_file)


def main(argv: Sequence[str] | None = None) -> int:
    given = list(sys.argv[1:] if argv is None else argv)
    who = given[given.index("--id") + 1] if "--id" in given[:-1] else ""
    return run_main(_main, argv, prog=f"zswarm agent {who}".strip())


if __name__ == "__main__":
    sys.exit(main())
