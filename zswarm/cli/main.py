"""``zswarm`` / ``python -m zswarm``: one entry point, a subcommand per task.

``zswarm run`` and ``zswarm sweep`` have parsers of their own (:mod:`zswarm.cli.launch`,
:mod:`zswarm.cli.sweep`); every other command's arguments are declared here or by its module.
"""

from __future__ import annotations

import argparse
import sys
from types import ModuleType
from typing import Sequence

from zswarm.args import Parser, run_main

DELEGATED = {"run": "start a swarm: router, world and N agent processes (zswarm run --help)",
             "sweep": "sweep latency x dropout, distributed and simulated (zswarm sweep --help)"}


def module_command(sub: argparse._SubParsersAction, name: str, text: str, module: ModuleType) -> None:
    """A subcommand whose module has ``DESCRIPTION``, ``add_arguments(parser)`` and ``run(args)``."""
    p = sub.add_parser(name, help=text, description=module.DESCRIPTION)
    module.add_arguments(p)
    p.set_defaults(run=module.run)


def build_parser() -> Parser:
    from zswarm.cli import (bench_bodies, bench_laws, bench_guidelines, bench_interactions, bench_net, bench_placement,
                            bench_safety, bench_world, certs, design, export, laws, monitor, replay, robot_sim, sim,
                            soak, tune)

    parser = Parser(prog="zswarm", description="Decentralized APF swarms (Kim, Wang & Shin 2006).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    d = sub.add_parser("design", help="check a parameter set against Propositions 1-5",
                       description="Check a parameter set against the paper's design guidelines. "
                                   "Exit 0 when all hold, 1 when one fails, 2 on a usage error.")
    design.add_arguments(d)
    d.set_defaults(run=design.run)

    s = sub.add_parser("sim", help="run the centralized reference simulation of a scenario",
                       description="Simulate a scenario with the vectorized reference simulator.")
    sim.add_sim_arguments(s)
    s.set_defaults(run=sim.run_sim)

    module_command(sub, "laws", "list the control laws (built-in, installed), their parameters and needs", laws)
    module_command(sub, "tune", "search the parameters that pass the guidelines and perform best", tune)
    module_command(sub, "monitor", "watch a running swarm live from any machine on its router", monitor)
    module_command(sub, "robot-sim", "stand-in ROS 2 robots (odometry, cmd_vel) to rehearse a deployment",
                   robot_sim)

    scen = sub.add_parser("scenarios", help="list the registered scenarios")
    scen.add_argument("--json", action="store_true")
    scen.set_defaults(run=sim.run_scenarios)

    for name, text in DELEGATED.items():  # listed in --help; parsed by their own modules
        sub.add_parser(name, help=text, add_help=False)

    bench = sub.add_parser("bench", help="benchmarks")
    bench_sub = bench.add_subparsers(dest="bench", required=True, parser_class=Parser)
    bs = bench_sub.add_parser("sim", help="simulator steps per second for growing N")
    sim.add_bench_sim_arguments(bs)
    bs.set_defaults(run=sim.run_bench_sim)
    module_command(bench_sub, "net", "distributed swarm: latency, ticks on time, load, memory", bench_net)
    module_command(bench_sub, "soak", "a long run under loss: memory flat? backlog growing?", soak)
    module_command(bench_sub, "guidelines", "do the design checks predict the swarm? (false-safe sets)",
                   bench_guidelines)
    module_command(bench_sub, "interactions", "each interaction on the same scenario, sizes and seeds",
                   bench_interactions)
    module_command(bench_sub, "laws", "the laws side by side on the same seeds and faults, filter off and on",
                   bench_laws)
    module_command(bench_sub, "bodies", "what each body costs on the registered scenarios", bench_bodies)
    module_command(bench_sub, "safety", "the safety filter beside the law alone and ORCA, same runs", bench_safety)
    module_command(bench_sub, "placement", "neighbour traffic crossing between routers: space vs round-robin",
                   bench_placement)
    module_command(bench_sub, "world", "what the world costs at N agents (crowd processes carry their poses)",
                   bench_world)

    replay.add_arguments(sub)
    module_command(sub, "export", "write a recorded run as ROS 2 messages (MCAP, for Foxglove and ros2 bag)", export)

    c = sub.add_parser("certs", help="make a CA, certificates and Zenoh configs for TLS + access control",
                       description=certs.DESCRIPTION)
    certs.add_arguments(c)
    c.set_defaults(run=certs.run)
    return parser


def _main(argv: Sequence[str] | None) -> int:
    args: argparse.Namespace = build_parser().parse_args(argv)
    return int(args.run(args))


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] in (["run"], ["sweep"]):
        return _delegate(argv[0], argv[1:], f"zswarm {argv[0]}")
    return run_main(_main, argv, prog=command_prog(argv))


def command_prog(argv: Sequence[str]) -> str:
    """``zswarm CMD`` (``zswarm bench CMD``) for ``argv``: what every error line of that command begins with."""
    words = []
    for arg in argv[:2]:
        if arg.startswith("-"):
            break
        words.append(arg)
        if arg != "bench":
            break
    return " ".join(["zswarm", *words])


def launch_main(argv: Sequence[str] | None = None) -> int:
    """``python launch.py [sweep] ...``: the README's front door, the same as ``zswarm run|sweep``."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["sweep"]:
        return _delegate("sweep", argv[1:], "launch.py sweep")
    return _delegate("run", argv, "launch.py")


def _delegate(command: str, argv: list[str], prog: str) -> int:
    if command == "run":
        from zswarm.cli import launch

        return launch.main(argv, prog=prog)
    from zswarm.cli import sweep

    return run_main(lambda a: sweep.main(a, prog=prog), argv, prog=prog)


if __name__ == "__main__":
    sys.exit(main())
