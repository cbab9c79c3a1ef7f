"""``zswarm monitor --run RUN``: a live terminal view of a running swarm, from any machine on its router.

Like ``ros2 topic hz`` and ``ros2 topic echo`` together for a whole run, refreshed in place (``rich``)
until the run ends (one line says how, exit 0), Ctrl-C or ``--stop-after``; ``--json`` prints one
object per refresh. It joins with the standard Zenoh arguments and only subscribes.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
import time

from zswarm.args import positive_seconds, renamed, wall_seconds
from zswarm.errors import UsageError
from zswarm.net.keys import Keys, check_run_id

DESCRIPTION = ("Watch a running swarm live: agents alive, pose rate per agent, latency and data age (p50/p99), "
               "rejected messages, late ticks and the prey, until the run ends (exit 0, one line that says how). "
               "Join with --connect tcp/ROUTER:PORT (or --config for TLS). Exit 2 when no agent is heard within --wait.")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from zswarm.net.config import add_zenoh_args

    parser.add_argument("--run", dest="run_id", required=True, metavar="RUN",
                        help="the run id (zswarm run prints it); a run elsewhere also needs --connect")
    parser.add_argument("--every", type=positive_seconds, default=1.0, metavar="S", help="refresh period (default 1 s)")
    parser.add_argument("--stop-after", type=wall_seconds, default=None, metavar="S",
                        help="stop after S seconds of the wall clock (default: when the run ends)")
    renamed(parser, "--duration", "the monitor runs on the wall clock: give --stop-after S")
    parser.add_argument("--wait", type=positive_seconds, default=10.0, metavar="S",
                        help="give up (exit 2) if no agent of the run is heard within S seconds (default 10)")
    parser.add_argument("--json", action="store_true", help="one JSON object per refresh instead of the table")
    add_zenoh_args(parser)


def table(snap, run: str):
    from rich.table import Table

    crashed = [i for i, how in snap.gone.items() if how == "crashed"]
    t = Table(title=f"zswarm run {run!r}: {len(snap.alive)} agents alive, {snap.agents_reporting} reporting stats"
                    + (f", CRASHED: {', '.join(map(str, crashed))}" if crashed else ""), title_justify="left")
    t.add_column("figure")
    t.add_column("value", justify="right")
    rate = snap.mean_pose_rate
    rates = [snap.pose_rate.get(i, 0.0) for i in snap.alive]
    fmt = lambda v, unit="": "-" if v is None else f"{v:.2f}{unit}"  # noqa: E731
    t.add_row("pose rate per agent (mean, min-max)",
              f"{fmt(rate, ' Hz')} ({min(rates):.1f}-{max(rates):.1f})" if rates else "-")
    t.add_row("pose latency p50 / p99", f"{fmt(snap.latency_p50_ms)} / {fmt(snap.latency_p99_ms, ' ms')}")
    t.add_row("data age at use p50 / p99", f"{fmt(snap.age_p50_ms)} / {fmt(snap.age_p99_ms, ' ms')}")
    t.add_row("late ticks", f"{snap.late_ticks} of {snap.ticks}")
    t.add_row("rejected messages", ", ".join(f"{k} {v}" for k, v in snap.rejected.items()) or "none")
    t.add_row("prey", "-" if snap.prey is None
              else f"({', '.join(f'{c:.2f}' for c in snap.prey)}) at {snap.prey_rate:.1f} Hz")
    slow = [i for i in snap.alive if snap.pose_rate.get(i, 0.0) < 0.5 * (rate or 0.0)]
    t.add_row("agents at under half the mean rate", ", ".join(map(str, slow)) or "none")
    slowest = sorted(snap.alive, key=lambda i: (snap.pose_rate.get(i, 0.0), i))[:SLOWEST]
    t.add_row(f"pose rate, slowest {len(slowest)}" if len(snap.alive) > SLOWEST else "pose rate, each (slowest first)",
              ", ".join(f"{i}: {snap.pose_rate.get(i, 0.0):.1f}" for i in slowest) or "-")
    t.add_row("gone", ", ".join(f"{i} ({how})" for i, how in snap.gone.items()) or "none")
    return t


#: The live view lists each agent's pose rate up to this many agents, else the slowest this many.
SLOWEST = 8


def run(args: argparse.Namespace) -> int:
    from zswarm.net.config import config_from_args, open_session
    from zswarm.net.watch import RunWatch

    check_run_id(args.run_id)
    if not args.connect:  # a run of this machine, found by its name: its router, and how to join it over TLS
        from zswarm.launch.local_runs import endpoint_of, runs_dir

        found = endpoint_of(args.run_id)
        if found is None and args.config is None:
            raise UsageError(f"no run {args.run_id!r} is running on this machine (its runs are listed in "
                             f"{runs_dir()}); for a run elsewhere give --connect tcp/ROUTER:PORT (zswarm run "
                             "prints its router)")
        if found is not None:
            args.connect = [found[0]]
            args.config = args.config or found[1]
    session = open_session(config_from_args(args), retry_for=args.connect_timeout)
    watch = RunWatch(Keys(args.run_id, cell_size=1.0))  # the wildcards it subscribes to span every cell
    stopping: list[int] = []  # the signal that asked this view to stop, once one has
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _: stopping.append(signum))
    start = time.monotonic()
    try:
        watch.start(session)
        while not stopping:  # wait for the first agent
            watch.poll()
            if watch.alive or watch.poses:
                break
            if time.monotonic() - start > args.wait:
                raise UsageError(f"no agent of run {args.run_id!r} heard within {args.wait:g} s; check --run (zswarm run "
                                 "prints it) and that --connect reaches the run's router")
            time.sleep(0.05)
        if args.json:
            _loop_json(watch, args, start, lambda: bool(stopping))
        else:
            _loop_live(watch, args, start, lambda: bool(stopping))
        if watch.over(now := time.time()):
            print(f"zswarm monitor: {watch.ending(now)}", file=sys.stderr if args.json else sys.stdout, flush=True)
    finally:
        watch.stop(session)
    return 0


def _ended(args, start: float, stopped, watch) -> bool:
    return (stopped() or (args.stop_after is not None and time.monotonic() - start >= args.stop_after)
            or watch.over(time.time()))


def _sleep(args, start: float, stopped, watch) -> None:
    """Up to one refresh period, taking in what arrives: the run's end cuts it short."""
    end = time.monotonic() + args.every
    while time.monotonic() < end and not _ended(args, start, stopped, watch):
        time.sleep(0.05)
        watch.poll()


def _loop_json(watch, args, start: float, stopped) -> None:
    while not _ended(args, start, stopped, watch):
        _sleep(args, start, stopped, watch)
        print(json.dumps(watch.snapshot().to_dict()), flush=True)


def _loop_live(watch, args, start: float, stopped) -> None:
    from rich.console import Console
    from rich.live import Live

    watch.poll()
    console = Console(file=sys.stdout)
    with Live(table(watch.snapshot(), args.run_id), console=console, auto_refresh=False) as live:
        while not _ended(args, start, stopped, watch):
            _sleep(args, start, stopped, watch)
            live.update(table(watch.snapshot(), args.run_id), refresh=True)
    if not console.is_terminal:  # a terminal's view ends its last line itself
        console.line()
