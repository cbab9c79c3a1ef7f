"""Zenoh session configuration from the standard arguments of the zenoh-python examples, and opening
a session with a bounded retry and one-line errors."""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path
from typing import Iterable

import zenoh

from zswarm.args import ZenohEndpoint, seconds
from zswarm.errors import UsageError
from zswarm.ports import LOOPBACK, local_host, port_in_use


#: How long a process keeps trying to reach its router at start (``--connect-timeout``), and a machine
#: started by hand waits for the router of its ``--connect``.
CONNECT_TIMEOUT = 15.0


def add_zenoh_args(parser: argparse.ArgumentParser, default_mode: str = "client") -> None:
    """The standard Zenoh arguments of the zenoh-python examples (``--connect`` is a Zenoh endpoint in
    every command; a Rerun viewer is ``--viewer``)."""
    group = parser.add_argument_group("zenoh")
    group.add_argument("--mode", choices=("peer", "client", "router"), default=None,
                       help=f"zenoh session mode (default: the --config file's, else {default_mode})")
    group.add_argument("--connect", "-e", action=ZenohEndpoint, default=[], metavar="ENDPOINT",
                       help="zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    group.add_argument("--listen", "-l", action=ZenohEndpoint, default=[], metavar="ENDPOINT",
                       help="endpoint to listen on, e.g. tcp/0.0.0.0:7447 (repeatable)")
    group.add_argument("--config", "-c", type=Path, metavar="FILE",
                       help="a full zenoh configuration file (json5), e.g. one written by 'zswarm certs' "
                            "for TLS and access control; the other flags override it")
    parser.set_defaults(default_mode=default_mode)
    group.add_argument("--scout", action="store_true",
                       help="enable multicast scouting (off by default so runs never meet by accident)")
    group.add_argument("--connect-timeout", type=seconds, default=CONNECT_TIMEOUT, metavar="S",
                       help=f"keep trying to reach the router this long at start (default {CONNECT_TIMEOUT:g} s)")


def zenoh_config(mode: str | None = "client", connect: Iterable[str] = (), listen: Iterable[str] = (),
                 config: Path | None = None, scout: bool = False) -> zenoh.Config:
    """A session configuration: the file ``config`` (if any), then the flags over it. ``mode=None``
    keeps the file's mode."""
    if config is not None:
        if Path(config).is_dir():
            raise UsageError(f"cannot read zenoh config {config}: it is a directory; give a .json5 file")
        if not Path(config).is_file():
            raise UsageError(f"zenoh config file {config} does not exist")
        try:
            conf = zenoh.Config.from_file(str(config))
        except Exception as exc:  # zenoh reports parse errors as ZError
            raise UsageError(f"cannot read zenoh config {config}: {_first_line(exc)}") from None
        for key, path in tls_files(conf, Path(config).resolve().parent).items():
            conf.insert_json5(f"{TLS}/{key}", json.dumps(str(path)))
    else:
        conf = zenoh.Config()
    if mode is not None or config is None:
        conf.insert_json5("mode", json.dumps(mode or "client"))
    connect, listen = list(connect), list(listen)
    for flag, endpoints in (("connect", connect), ("listen", listen)):
        for endpoint in endpoints:  # at once, one line: not a session retrying what cannot exist
            endpoint_host_port(endpoint)
        if endpoints:
            try:
                conf.insert_json5(f"{flag}/endpoints", json.dumps(endpoints))
            except Exception:  # zenoh reports a malformed endpoint as ZError
                raise UsageError(f"--{flag} {' '.join(endpoints)}: an endpoint looks like tcp/HOST:PORT "
                                 f"(or tls/HOST:PORT)") from None
    if config is None or scout:
        conf.insert_json5("scouting/multicast/enabled", json.dumps(bool(scout)))
    # No shared-memory transport: a swarm's messages are under 100 bytes, far below the 3 KB from
    # which Zenoh would use it, and with it on (the default) a router on the same host as its clients
    # accepted only about 350 of them: 351-353 of 400 connected on a 16-core machine, the router
    # logging "No available SHM counters" for each refused handshake (docs/benchmarks.md).
    conf.insert_json5("transport/shared_memory/enabled", "false")
    return conf


DEFAULT_ROUTER = f"tcp/{LOOPBACK}:7447"

#: Where a Zenoh configuration names its TLS files, and the keys that name them.
TLS = "transport/link/tls"
TLS_FILES = ("root_ca_certificate", "connect_private_key", "connect_certificate", "listen_private_key",
             "listen_certificate")


def tls_files(conf: zenoh.Config, folder: Path) -> dict[str, Path]:
    """The TLS files ``conf`` names, a relative path taken from ``folder`` (the config file's own: unlike
    ``zenohd``, which reads it from the working directory), so that a folder of configs and their files
    can be moved or copied whole (docs/running.md)."""
    out = {}
    for key in TLS_FILES:
        try:
            value = json.loads(conf.get_json(f"{TLS}/{key}"))
        except Exception:  # noqa: BLE001 (zenoh: no such key)
            continue
        if isinstance(value, str) and value:
            out[key] = Path(value) if Path(value).is_absolute() else folder / value
    return out


def _first_line(exc: Exception) -> str:
    """A zenoh error without the Rust source location it carries."""
    return (str(exc).splitlines() or [""])[0].split(" at /")[0].split(" at ")[0].strip()


ENDPOINT_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream")


def endpoint_host_port(endpoint: str) -> tuple[str, int]:
    """The host and port of a Zenoh endpoint ``PROTO/HOST:PORT``; a :class:`UsageError` (one line) when it
    is not one, at once, instead of a session that retries an address that cannot exist."""
    import ipaddress

    proto, sep, rest = endpoint.partition("/")
    host, colon, port_text = rest.rpartition(":")
    host = host.strip("[]")
    form = "must look like tcp/HOST:PORT (or tls/HOST:PORT)"
    if not sep or not colon or not host or proto not in ENDPOINT_PROTOCOLS:
        raise UsageError(f"endpoint {endpoint!r} {form}")
    try:
        port = int(port_text)
    except ValueError:
        raise UsageError(f"endpoint {endpoint!r} {form}: {port_text!r} is not a port") from None
    if not 0 < port < 65536:
        raise UsageError(f"endpoint {endpoint!r}: the port must be in 1..65535 (got {port})")
    if all(part.isdigit() for part in host.split(".")) or ":" in host:
        try:
            ipaddress.ip_address(host)
        except ValueError:
            raise UsageError(f"endpoint {endpoint!r}: {host} is not an IP address") from None
    return host, port


def config_from_args(args: argparse.Namespace) -> zenoh.Config:
    """A client with nothing to connect to joins the default local router."""
    connect = args.connect
    mode = args.mode or (None if args.config is not None else args.default_mode)
    if mode == "client" and not connect and args.config is None and not args.scout:
        connect = [DEFAULT_ROUTER]
    return zenoh_config(mode, connect, args.listen, args.config, args.scout)


# One tokio worker for Zenoh's own tasks, instead of a pool per runtime: a swarm runs tens of
# processes on few cores, and idle worker pools only compete for them. Measured with
# `zswarm bench net --agents 50` on 2 cores, three runs each: p99 latency 56-64 ms instead of
# 133-208 ms, 99.3 % of ticks on time instead of 97.7 %, for a higher median (14-17 ms, not 8-11);
# no change at N = 10. Set ZENOH_RUNTIME yourself to override.
LEAN_RUNTIME = ("(app: (worker_threads: 1), acc: (handover: app), tx: (handover: app), "
                "rx: (handover: app), net: (handover: app))")


def unreachable(endpoint: str, waited: float) -> str:
    """The one line every command says when the router it was told to reach does not answer (exit 2)."""
    return (f"cannot reach the router at {endpoint} within {waited:g} s: is it running, and its port open to this "
            "machine? (--connect, --connect-timeout)")


def connected(session: zenoh.Session) -> bool:
    """The session has a router or a peer to speak to (a router that died: none, at once)."""
    return any(True for _ in session.info.routers_zid()) or any(True for _ in session.info.peers_zid())


def _answers(endpoint: str) -> bool:
    """Something accepts a TCP connection on ``endpoint``'s port (a router that runs, or something else)."""
    try:
        host, port = endpoint_host_port(endpoint)
    except UsageError:
        return False
    return port_in_use(local_host(host), port, timeout=0.5)


def open_session(conf: zenoh.Config, what: str = "", retry_for: float = 0.0,
                 runtime: str | None = LEAN_RUNTIME) -> zenoh.Session:
    """Open a session, retrying for ``retry_for`` seconds (a router that is still starting); then an
    unreachable router or a taken port is a one-line :class:`UsageError` (beginning ``what: `` where the
    command's own name does not say which of its sessions it is). Zenoh's runtime is
    ``runtime`` (default the lean one, :data:`LEAN_RUNTIME`; None: Zenoh's own pools) unless
    ``ZENOH_RUNTIME`` says otherwise."""
    if runtime is not None:
        os.environ.setdefault("ZENOH_RUNTIME", runtime)
    if os.environ.get("RUST_LOG"):  # Zenoh's own log on stderr, e.g. RUST_LOG=zenoh=debug
        zenoh.init_log_from_env_or("error")

    lead = f"{what}: " if what else ""
    deadline = time.monotonic() + retry_for
    while True:
        try:
            return zenoh.open(conf)
        except Exception as exc:
            first = _first_line(exc)
            if "listener" in first or "in use" in first:
                raise UsageError(f"{lead}cannot listen: {first} (the port is taken or the address is not "
                                 f"local: pick another --listen)") from None
            if time.monotonic() >= deadline:
                connect = json.loads(conf.get_json("connect/endpoints") or "[]")
                if connect and not any(_answers(e) for e in connect):
                    raise UsageError(f"{lead}{unreachable(', '.join(connect), retry_for)}") from None
                waited = f" after {retry_for:g} s" if retry_for > 0 else ""
                raise UsageError(f"{lead}cannot open a zenoh session{waited}: {first} (something answers on the "
                                 "port: is it a Zenoh router, with this run's certificates? check --connect, "
                                 "--secure)") from None
            time.sleep(0.25)


