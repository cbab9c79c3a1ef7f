"""``--cluster local[:K]``: K Ray nodes on this machine, started as Ray tells users to start nodes
(``ray start --head`` and ``ray start --address``, each with ``--block``: the node lives as long as
its ``ray start`` process, a child of the driver), every one on a loopback address.

That address is :data:`RAY_LOOPBACK`, not 127.0.0.1: Ray replaces 127.0.0.1 and ``localhost``, in
``--node-ip-address``, ``--address`` and ``ray.init``, by the address of the interface that routes
towards 8.8.8.8, where a node started on loopback does not answer (ray-project/ray#59110). Linux routes
all of 127.0.0.0/8 to loopback, so no node depends on the machine's interfaces. docs/cluster.md.
"""

from __future__ import annotations

import json
import os
import selectors
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from zswarm.cluster.ray_env import OBJECT_STORE_BYTES, SYSTEM_CONFIG
from zswarm.errors import UsageError

#: Every node of a local cluster, and its driver, takes this address (see the module's docstring).
RAY_LOOPBACK = "127.0.0.2"
#: How long a node may take to start before the run gives up, in one line.
START_TIMEOUT_S = 60.0
#: What ``ray start --block`` prints once its node is up.
STARTED = b"Ray runtime started."


def kernel_port() -> int:
    """A port of :data:`RAY_LOOPBACK` nothing listens on, from the kernel's ephemeral range: not one of
    ``ZSWARM_PORTS``, which may overlap the ports Ray keeps for its workers (10002-19999), a clash Ray
    refuses a node for."""
    import socket

    with socket.socket() as s:
        s.bind((RAY_LOOPBACK, 0))
        return s.getsockname()[1]


def ray_command() -> str:
    """The ``ray`` command beside this interpreter (the one ``pip install -e ".[cluster]"`` put there)."""
    here = Path(sys.executable).parent / "ray"
    return str(here) if here.exists() else "ray"


def node_argv(cores: int, gcs_port: int, head: bool) -> list[str]:
    """``ray start`` for one node with ``cores``: the head, its GCS on ``gcs_port``, or a node that joins
    it there. Each node's dashboard agent gets a port of its own (Ray's default, 52365, is one a machine)."""
    argv = [ray_command(), "start", "--block", f"--node-ip-address={RAY_LOOPBACK}", f"--num-cpus={cores}",
            f"--object-store-memory={OBJECT_STORE_BYTES}", f"--dashboard-agent-listen-port={kernel_port()}",
            "--disable-usage-stats", "--log-style=record", "--include-log-monitor=false"]  # no worker log is read
    if head:  # no dashboard, no autoscaler: nothing scales a cluster of this machine's processes
        return [*argv, "--head", f"--port={gcs_port}", "--include-dashboard=false", "--no-monitor",
                f"--system-config={json.dumps(SYSTEM_CONFIG)}"]
    return [*argv, f"--address={RAY_LOOPBACK}:{gcs_port}"]


class LocalNodes:
    """The ``ray start --block`` processes of a local cluster; :meth:`close` ends every one."""

    def __init__(self) -> None:
        self.procs: list[subprocess.Popen] = []
        self.address = ""

    def start(self, k: int, cores: int, timeout: float = START_TIMEOUT_S) -> str:
        """Start the head, then ``k - 1`` nodes that join it, one after another (raylets started together
        bind the same port and abort), each with ``cores``; the head's ``HOST:PORT``. UsageError (one
        line, with Ray's last words) when a node is not up within ``timeout`` seconds or ends first."""
        port = kernel_port()
        deadline = time.monotonic() + timeout
        for n in range(k):
            self._up(node_argv(cores, port, head=n == 0), deadline, timeout)
        self.address = f"{RAY_LOOPBACK}:{port}"
        return self.address

    def _up(self, argv: list[str], deadline: float, timeout: float) -> None:
        """Start one node and read its output until it says it is up; then drain the rest (a full pipe
        would block it)."""
        proc = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                start_new_session=True)  # its own group: ended with everything it started
        self.procs.append(proc)
        said = read_until(proc, STARTED, deadline - time.monotonic())
        if STARTED not in said:
            try:  # its output ended before the deadline: so has it, or it is about to
                code = proc.wait(5.0) if time.monotonic() < deadline else None
            except subprocess.TimeoutExpired:
                code = None
            if code is None:
                raise UsageError(f"a Ray node on this machine did not start within {timeout:g} s "
                                 f"({_last(said)}); use --cluster ADDRESS with a cluster started by ray start")
            raise UsageError(f"a Ray node on this machine ended as it started (exit {code}): {_last(said)}")
        fd = proc.stdout.fileno()
        threading.Thread(target=lambda: [None for _ in iter(lambda: os.read(fd, 65536), b"")], daemon=True).start()

    def close(self, grace: float = 3.0) -> None:
        """SIGTERM to every node's process group (the head's last: ``ray start --block`` stops its node's
        processes), up to ``grace`` seconds for them to end, then SIGKILL to whatever is left in each group."""
        for proc in reversed(self.procs):
            _signal(proc, signal.SIGTERM)
        deadline = time.monotonic() + grace
        for proc in self.procs:
            try:
                proc.wait(max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                pass
            _signal(proc, signal.SIGKILL)
            proc.wait()
        self.procs = []


def read_until(proc: subprocess.Popen, marker: bytes | None, seconds: float) -> bytes:
    """What ``proc`` writes to its stdout, read straight from the pipe (a buffered reader would hold lines
    a selector no longer sees), until it has written ``marker`` (None: until it closes it) or ``seconds``
    have passed."""
    fd, said = proc.stdout.fileno(), b""
    deadline = time.monotonic() + seconds
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        while (marker is None or marker not in said) and (left := deadline - time.monotonic()) > 0:
            if sel.select(timeout=left):
                chunk = os.read(fd, 65536)
                if not chunk:
                    break
                said += chunk
    return said


def _signal(proc: subprocess.Popen, sig: int) -> None:
    try:
        os.killpg(proc.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def _last(said: bytes) -> str:
    """The last line of Ray's output that says something."""
    lines = [ln.strip() for ln in said.decode(errors="replace").splitlines() if ln.strip("- \t")]
    return lines[-1][-200:] if lines else "it printed nothing"
