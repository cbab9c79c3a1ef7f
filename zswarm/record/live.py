"""Where a recording goes while it is written: a file, a Rerun viewer, or both at once.

After Rerun's conventions (``rr.script_add_args``): ``--spawn`` starts a viewer and streams to it,
``--viewer [URL]`` streams to one that is running (default ``rerun+http://127.0.0.1:9876/proxy``,
what ``rerun`` listens on; Rerun's own scripts call it ``--connect``, which in zswarm is always a Zenoh
endpoint), ``--serve`` hosts a gRPC server in this process and a web viewer connected
to it. zswarm records to a file by default, so a viewer is asked for, never assumed; with ``--record``
(or zswarm run's default file) the same stream goes to both (``set_sinks``).

A viewer address is checked before anything starts: one that nothing listens on is a one-line usage
error, not a run that silently streams into the void.
"""

from __future__ import annotations

import argparse
import socket
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

from zswarm.args import renamed, viewer_url
from zswarm.args import DEFAULT_VIEWER_URL as DEFAULT_URL
from zswarm.errors import UsageError
from zswarm.ports import LOOPBACK
from zswarm.ports import free_port

SERVE_PORT = 9876
WEB_PORT = 9090


@dataclass(frozen=True)
class Viewer:
    spawn: bool = False
    connect: str | None = None
    serve: bool = False

    @property
    def wanted(self) -> bool:
        return self.spawn or self.connect is not None or self.serve

    def to_argv(self) -> list[str]:
        """The flags that ask a child (the world) for the same viewer."""
        out = ["--spawn"] if self.spawn else []
        out += ["--viewer", self.connect] if self.connect is not None else []
        return out + (["--serve"] if self.serve else [])


def check_reachable(url: str, timeout: float = 2.0) -> None:
    """One line if nothing listens at a viewer URL (a gRPC proxy: ``rerun`` or ``rerun --serve-grpc``)."""
    parsed = urlparse(url.replace("rerun+", "", 1) if url.startswith("rerun+") else url)
    host, port = parsed.hostname, parsed.port
    if not host or not port:
        raise UsageError(f"--connect {url}: expected a viewer URL like {DEFAULT_URL}")
    try:
        with socket.create_connection((host, port), timeout=timeout):
            pass
    except OSError as exc:
        raise UsageError(f"--viewer {url}: no Rerun viewer answers there ({exc.strerror or exc}); start one "
                         "with 'rerun' (or 'rerun --serve-grpc'), or use --spawn") from None


def add_viewer_args(parser: argparse.ArgumentParser, zenoh: bool = True) -> None:
    """``--spawn``, ``--viewer [URL]`` and ``--serve``; a program that speaks no Zenoh (``zenoh=False``)
    refuses ``--connect`` with the hint ``--viewer``."""
    group = parser.add_argument_group("live viewing (Rerun)")
    group.add_argument("--spawn", action="store_true", help="start a Rerun viewer and stream the run to it live")
    group.add_argument("--viewer", dest="viewer_connect", type=viewer_url, nargs="?", const=DEFAULT_URL,
                       default=None, metavar="URL",
                       help=f"stream live to a running Rerun viewer (default URL {DEFAULT_URL})")
    group.add_argument("--serve", action="store_true",
                       help=f"host a gRPC server (port {SERVE_PORT}) and a web viewer (http://localhost:{WEB_PORT}) "
                            "streaming the run live")
    if not zenoh:
        renamed(parser, "--connect", "this command joins no Zenoh router; stream to a Rerun viewer with --viewer [URL]")


def viewer_from_args(args: argparse.Namespace) -> Viewer:
    viewer = Viewer(spawn=args.spawn, connect=args.viewer_connect, serve=args.serve)
    if viewer.connect is not None:
        check_reachable(viewer.connect)
    if viewer.serve:
        for port in (SERVE_PORT, WEB_PORT):
            check_port_free(port)
    return viewer


def check_port_free(port: int) -> None:
    """``--serve`` listens on fixed ports: one line, before anything starts, if something holds one."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("0.0.0.0", port))
        except OSError:
            raise UsageError(f"--serve: port {port} is in use (another run serving live?); stop it, or stream "
                             "this run with --spawn or --connect URL") from None


def sinks(path: Path | None, viewer: Viewer | None) -> list:
    """The Rerun sinks for a file and/or a viewer (starting the viewer or the server where asked)."""
    import rerun as rr

    out: list = [rr.FileSink(str(path))] if path is not None else []
    viewer = viewer or Viewer()
    if viewer.spawn:
        out.append(rr.GrpcSink(spawn_viewer()))
    if viewer.connect is not None:
        out.append(rr.GrpcSink(viewer.connect))
    if viewer.serve:
        server = rr.GrpcServerSink(port=SERVE_PORT)
        out.append(server)
        uri = server.uri.replace("0.0.0.0", LOOPBACK)  # it listens on every interface
        rr.serve_web_viewer(web_port=WEB_PORT, open_browser=False, connect_to=uri)
        print(f"serving the run live: open http://localhost:{WEB_PORT} (or: rerun --connect {uri})", flush=True)
    return out


def spawn_viewer() -> str:
    """Start a Rerun viewer (its own process, on a free port) and return the URL to stream to."""
    import rerun as rr

    port = free_port()
    try:
        rr.spawn(port=port, connect=False)
    except Exception as exc:  # no `rerun` on PATH, no display: say so, in one line
        raise UsageError(f"--spawn: cannot start the Rerun viewer ({exc}); run 'rerun' yourself and use "
                         "--connect, or --serve for a browser") from None
    return f"rerun+http://{LOOPBACK}:{port}/proxy"
