"""``zswarm export RUN.rrd --mcap RUN.mcap``: a recorded run as ROS 2 messages (:mod:`zswarm.ros.export`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from zswarm.args import UsageError

DESCRIPTION = ("Write a recorded run as ROS 2 messages in one MCAP file: each agent's PoseStamped, the prey, "
               "the obstacles as a MarkerArray and the metrics as Float64 topics, to open in Foxglove or play "
               "with 'ros2 bag play RUN.mcap'.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", type=Path, metavar="RUN.rrd")
    parser.add_argument("--mcap", type=Path, required=True, metavar="RUN.mcap", help="the MCAP file to write")
    parser.add_argument("--distro", default="jazzy", choices=("humble", "jazzy", "kilted", "rolling"),
                        help="whose message definitions the file carries (default jazzy)")
    parser.add_argument("--force", action="store_true", help="overwrite an existing --mcap file")


def run(args: argparse.Namespace) -> int:
    from zswarm.record.replay import load_run, observer_of, scenario_of
    from zswarm.ros.export import export_mcap

    if args.mcap.suffix != ".mcap":
        raise UsageError(f"--mcap {args.mcap} must end in .mcap")
    if args.mcap.exists() and not args.force:
        raise UsageError(f"{args.mcap} exists; give another path or --force")
    if not args.mcap.parent.is_dir():
        raise UsageError(f"the folder of --mcap {args.mcap} does not exist")
    from zswarm.files import check_writable

    check_writable(args.mcap, (".mcap",))  # a folder it may not write (/sys): one line, before any work
    run = load_run(args.recording)
    counts = export_mcap(run, scenario_of(run), observer_of(run), args.mcap, args.distro)
    agents = sum(1 for topic in counts if topic.startswith("/swarm/agent_"))
    print(f"export: {args.mcap}: {sum(counts.values())} messages on {len(counts)} topics ({agents} agents' poses, "
          f"the prey, {counts.get('/swarm/obstacles', 0)} obstacle array, "
          f"{sum(1 for t in counts if t.startswith('/swarm/metrics/'))} metrics)")
    return 0
