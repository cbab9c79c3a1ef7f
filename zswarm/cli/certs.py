"""``zswarm certs DIR``: a private CA, a certificate per role (and per agent) and the Zenoh configs
for mutual TLS with access control (:mod:`zswarm.net.security`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from zswarm.args import UsageError, agent_count, positive_int
from zswarm.ports import LOOPBACK

DESCRIPTION = ("Write ca.pem, NAME.pem/.key and NAME.json5 (a full Zenoh config with mutual TLS; the router's "
               "with access control) for router, world and agent into DIR. Use them with 'zswarm run --secure "
               "DIR', or pass --config DIR/ROLE.json5 to each process on its own machine.")


def add_arguments(certs: argparse.ArgumentParser) -> None:
    certs.add_argument("directory", type=Path, metavar="DIR")
    certs.add_argument("--router", default="tls/localhost:7447", metavar="ENDPOINT",
                       help="the router's endpoint written into the configs (default tls/localhost:7447)")
    certs.add_argument("--hosts", default=f"localhost,{LOOPBACK}", metavar="H1,H2",
                       help="names and addresses the router is reached by (certificate SANs)")
    certs.add_argument("--extra", default="", metavar="NAME,..",
                       help="more certificates with no rights (e.g. guest) for testing")
    certs.add_argument("--agents", type=agent_count, default=0, metavar="N",
                       help="also give agents 0..N-1 an identity each (agent-I), allowed only their own keys; "
                            "the router's access control then holds N rules (default 0: one shared identity)")
    certs.add_argument("--days", type=positive_int, default=30, help="validity (default 30)")
    certs.add_argument("--bundle", type=Path, default=None, metavar="OUT",
                       help="write into OUT only what another machine needs: ca.pem and the key, certificate and "
                            "config of each identity --names picks, never ca.key (docs/running.md)")
    certs.add_argument("--names", default="", metavar="PATTERN,..",
                       help="with --bundle: the identities to copy, e.g. world or 'agent-*' (shell patterns)")
    certs.add_argument("--force", action="store_true",
                       help="make a new CA even where DIR has one (by default its CA is reused and signs the new certificates)")


def run(args: argparse.Namespace) -> int:
    from zswarm.net.certs import ROLES, check_hosts, write_bundle
    from zswarm.net.security import write_secure_dir

    if args.bundle is not None:
        patterns = [n for n in args.names.split(",") if n]
        if not patterns:
            raise UsageError("--bundle needs --names: the identities that machine runs, e.g. --names 'agent-*'")
        names = write_bundle(args.directory, args.bundle, patterns)
        print(f"{args.bundle}: ca.pem and {', '.join(names)} (no ca.key); copy it to the machine that runs them")
        return 0
    if args.names:
        raise UsageError("--names goes with --bundle OUT")
    ca = [args.directory / "ca.pem", args.directory / "ca.key"]
    if args.force:
        for path in ca:
            path.unlink(missing_ok=True)
    elif ca[0].exists() and not ca[1].is_file():
        raise UsageError(f"{args.directory} has a CA certificate but not its key (ca.key), so it cannot sign: "
                         "copy ca.key there, or give --force to make a new CA (every role then needs the new files)")
    elif ca[0].exists():
        print(f"reusing the CA in {args.directory} (--force makes a new one)")
    if not args.router.startswith("tls/"):
        raise UsageError(f"--router {args.router!r} must be a tls/HOST:PORT endpoint")
    if args.agents < 0:
        raise UsageError(f"--agents must be >= 0 (got {args.agents})")
    extra = tuple(n for n in args.extra.split(",") if n)
    hosts = check_hosts([h.strip() for h in args.hosts.split(",") if h.strip()])
    try:
        written = write_secure_dir(args.directory, args.router, hosts, ROLES + extra, args.days, args.agents)
    except OSError as exc:
        raise UsageError(f"cannot write to {args.directory}: {exc.strerror}") from None
    for name, path in written.items():
        print(f"{name}: {path} (certificate {path.with_suffix('.pem').name})")
    return 0
