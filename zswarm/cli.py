"""``zswarm`` / ``python -m zswarm``: one entry point, a subcommand per task."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Sequence

from zswarm.cli_util import Parser, run_main


def build_parser() -> Parser:
    from zswarm import design_cli, sim_cli

    parser = Parser(prog="zswarm", description="Decentralized APF swarms (Kim, Wang & Shin 2006).")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    design = sub.add_parser("design", help="check a parameter set against Propositions 1-5",
                            description="Check a parameter set against the paper's design guidelines. "
                                        "Exit 0 when all hold, 1 when one fails, 2 on a usage error.")
    design_cli.add_arguments(design)
    design.set_defaults(run=design_cli.run)

    sim = sub.add_parser("sim", help="run the centralized reference simulation of a scenario",
                         description="Simulate a scenario with the vectorized reference simulator.")
    sim_cli.add_sim_arguments(sim)
    sim.set_defaults(run=sim_cli.run_sim)

    scen = sub.add_parser("scenarios", help="list the registered scenarios")
    scen.add_argument("--json", action="store_true")
    scen.set_defaults(run=sim_cli.run_scenarios)

    bench = sub.add_parser("bench", help="benchmarks")
    bench_sub = bench.add_subparsers(dest="bench", required=True, parser_class=Parser)
    bench_sim = bench_sub.add_parser("sim", help="simulator steps per second for growing N")
    sim_cli.add_bench_sim_arguments(bench_sim)
    bench_sim.set_defaults(run=sim_cli.run_bench_sim)
    bench_net = bench_sub.add_parser("net", help="distributed swarm: latency, ticks on time, load, memory")
    bench_net.add_argument("--agents", type=lambda s: [sim_cli.positive_int(x) for x in s.split(",")],
                           default=[10], help="N, or a comma-separated list (default 10)")
    bench_net.add_argument("--duration", type=sim_cli.positive_float, default=15.0,
                           help="simulated = wall seconds per run (default 15)")
    bench_net.add_argument("--json", action="store_true")
    bench_net.set_defaults(run=_bench_net)
    soak = bench_sub.add_parser("soak", help="a long run under loss: memory flat? backlog growing?",
                                description="N agents on bench-field with seeded loss for several minutes; "
                                            "samples every process's memory and the agents' inbound queues "
                                            "and tick lag. Exit 1 when memory or backlog grows.")
    soak.add_argument("--agents", type=sim_cli.positive_int, default=30, help="N (default 30)")
    soak.add_argument("--dropout", type=float, default=0.2, help="loss probability per message (default 0.2)")
    soak.add_argument("--duration", type=sim_cli.positive_float, default=300.0,
                      help="seconds (default 300)")
    soak.add_argument("--seed", type=int, default=0)
    soak.add_argument("--json", action="store_true")
    soak.set_defaults(run=_bench_soak)

    from zswarm import replay_cli

    replay_cli.add_arguments(sub)

    certs = sub.add_parser("certs", help="make a CA, certificates and Zenoh configs for TLS + access control",
                           description="Write ca.pem, NAME.pem/.key and NAME.json5 (a full Zenoh config with "
                                       "mutual TLS; the router's with access control) for router, world and "
                                       "agent into DIR. Use them with 'launch.py --secure DIR', or pass "
                                       "--config DIR/ROLE.json5 to each process on its own machine.")
    certs.add_argument("directory", type=Path, metavar="DIR")
    certs.add_argument("--router", default="tls/localhost:7447", metavar="ENDPOINT",
                       help="the router's endpoint written into the configs (default tls/localhost:7447)")
    certs.add_argument("--hosts", default="localhost,127.0.0.1", metavar="H1,H2",
                       help="names and addresses the router is reached by (certificate SANs)")
    certs.add_argument("--extra", default="", metavar="NAME,..",
                       help="more certificates with no rights (e.g. guest) for testing")
    certs.add_argument("--agents", type=int, default=0, metavar="N",
                       help="also give agents 0..N-1 an identity each (agent-I), allowed only their own keys; "
                            "the router's access control then holds N rules (default 0: one shared identity)")
    certs.add_argument("--days", type=sim_cli.positive_int, default=30, help="validity (default 30)")
    certs.add_argument("--force", action="store_true", help="overwrite an existing CA in DIR")
    certs.set_defaults(run=_certs)
    return parser


def _certs(args) -> int:
    from zswarm.certs import ROLES
    from zswarm.cli_util import UsageError
    from zswarm.security import write_secure_dir

    if (args.directory / "ca.pem").exists() and not args.force:
        raise UsageError(f"{args.directory} already has a CA; use --force to replace it (every role then "
                         f"needs the new files)")
    if not args.router.startswith("tls/"):
        raise UsageError(f"--router {args.router!r} must be a tls/HOST:PORT endpoint")
    if args.agents < 0:
        raise UsageError(f"--agents must be >= 0 (got {args.agents})")
    extra = tuple(n for n in args.extra.split(",") if n)
    hosts = tuple(h for h in args.hosts.split(",") if h)
    try:
        written = write_secure_dir(args.directory, args.router, hosts, ROLES + extra, args.days, args.agents)
    except OSError as exc:
        raise UsageError(f"cannot write to {args.directory}: {exc.strerror}") from None
    for name, path in written.items():
        print(f"{name}: {path} (certificate {path.with_suffix('.pem').name})")
    return 0


def _bench_soak(args) -> int:
    from zswarm.cli_util import UsageError
    from zswarm.soak import main_soak

    if not 0.0 <= args.dropout < 1.0:
        raise UsageError(f"--dropout must be in [0, 1) (got {args.dropout})")
    return main_soak(args)


def _bench_net(args) -> int:
    from zswarm.bench_net import main_bench

    return main_bench(args)


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    return int(args.run(args))


def main(argv: Sequence[str] | None = None) -> int:
    return run_main(_main, argv)


if __name__ == "__main__":
    sys.exit(main())
