"""``zswarm robot-sim --robots FILE.toml``: stand-in ROS 2 robots (:mod:`zswarm.ros.robot_sim`)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from zswarm.args import UsageError, add_param_args, seed_arg, renamed, wall_seconds, seconds
from zswarm.stopping import stop_on_signals

DESCRIPTION = ("Stand-in ROS 2 robots for rehearsing a deployment: differential-drive robots at the scenario's "
               "spawn positions that publish nav_msgs/Odometry and obey geometry_msgs/Twist on the wire of the "
               "robots file's route (rmw_zenoh or ros2dds), stopping when commands stop.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from zswarm.net.config import add_zenoh_args

    parser.add_argument("--robots", type=Path, required=True, metavar="FILE.toml", help="the robots file")
    parser.add_argument("--scenario", default="moving-prey", help="where the robots start: this scenario's "
                        "spawn positions for their agent ids (default moving-prey)")
    parser.add_argument("--seed", type=seed_arg, default=0, help="the run's seed (its spawn; default 0)")
    add_param_args(parser)
    parser.add_argument("--rate", type=float, default=50.0, help="odometry and dynamics rate in Hz (default 50)")
    parser.add_argument("--cmd-timeout", type=seconds, default=0.25,
                        help="stop a robot whose commands stopped this many seconds ago (default 0.25)")
    parser.add_argument("--stop-after", type=wall_seconds, default=None, metavar="S",
                        help="stop after S seconds of the wall clock (default: until the run ends, see --idle-exit, "
                             "or Ctrl-C)")
    renamed(parser, "--duration", "robot-sim runs on the wall clock: give --stop-after S")
    parser.add_argument("--idle-exit", type=seconds, default=5.0, metavar="S",
                        help="stop once the robots were commanded and then no command came for S seconds: "
                             "the run that drove them has ended (default 5; 0: never)")
    add_zenoh_args(parser)


def run(args: argparse.Namespace) -> int:
    from zswarm.paper.params import parse_assignments
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.net.config import config_from_args, open_session
    from zswarm.ros import robot_sim
    from zswarm.ros.robots import load_robots

    if not 1.0 <= args.rate <= 1000.0:
        raise UsageError(f"--rate must be in [1, 1000] Hz (got {args.rate})")
    if not 0.0 <= args.idle_exit <= 3600.0:
        raise UsageError(f"--idle-exit must be in [0, 3600] s (got {args.idle_exit})")
    if not 0.0 < args.cmd_timeout <= 10.0:
        raise UsageError(f"--cmd-timeout must be in (0, 10] s (got {args.cmd_timeout})")
    robots_file = load_robots(args.robots)
    scenario = get_scenario(args.scenario, parse_assignments(args.assignments))
    if scenario.dimensions != 2:
        raise UsageError(f"{args.scenario} is 3-D: ROS 2 ground robots (a unicycle each) need a 2-D scenario")
    spawn = scenario.initial_positions(np.random.default_rng(args.seed))
    facing = tuple(float(c) for c in scenario.prey_start)
    robots = []
    for r in robots_file.robots:
        if r.id >= len(spawn):
            raise UsageError(f"robot {r.namespace} drives agent {r.id}, which {scenario.name} (N = {len(spawn)}) "
                             "does not spawn; give it an id below N or --set n_agents=")
        start = robot_sim.start_pose(r, (float(spawn[r.id, 0]), float(spawn[r.id, 1])), facing)
        robots.append(robot_sim.SimRobot(r, robots_file.route, start, args.cmd_timeout))
    session = open_session(config_from_args(args), retry_for=args.connect_timeout)
    stop = stop_on_signals()
    route = robots_file.route
    print(f"robot-sim: {len(robots)} robots on {route.route} ({route.distro}, domain {route.domain_id}), "
          f"odometry at {args.rate:g} Hz, stopping {args.cmd_timeout:g} s after the last command", flush=True)
    try:
        why = robot_sim.run(session, route, robots, args.rate, stop, args.stop_after, args.idle_exit or None)
    finally:
        session.close()
    print(f"robot-sim: {why}", flush=True)
    for r in robots:
        rejected = ", ".join(f"{k} {v}" for k, v in sorted(r.rejected.items())) or "none"
        print(f"robot-sim: {r.robot.namespace}: {r.commands} commands, rejected {rejected}", flush=True)
    return 0
