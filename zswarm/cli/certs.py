"""``zswarm certs DIR``: a private CA, a certificate per role (and per agent) and the Zenoh configs
for mutual TLS with access control (:mod:`zswarm.net.security`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from zswarm.args import UsageError, positive_int
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
    certs.add_argument("--agents", type=int, default=0, metavar="N",
                       help="also give agents 0..N-1 an identity each (agent-I), allowed only their own keys; "
                            "the router's access control then holds N rules (default 0: one shared identity)")
    certs.add_argument("--days", type=positive_int, default=30, help="validity (default 30)")
    certs.add_argument("--force", action="store_true", help="overwrite an existing CA in DIR")


def run(args: argparse.Namespace) -> int:
    from zswarm.net.certs import ROLES
    from zswarm.net.security import write_secure_dir

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
