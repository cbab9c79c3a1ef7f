"""One machine of a cluster run: its Zenoh router and its share of agents, as ordinary OS processes.
:class:`NodeActor` is a plain class that :mod:`zswarm.cluster.hosts` makes a Ray actor pinned to its node;
every child dies with the actor's worker (``PR_SET_PDEATHSIG``), and under ``--secure`` a node makes its
own keys: docs/cluster.md."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import threading
from collections import deque
from pathlib import Path
from typing import Sequence

from zswarm.host.local import LocalHost
from zswarm.host.procs import Children


def node_address() -> str:
    """The address this node's router listens on: the one Ray knows this node by."""
    import ray

    return ray.util.get_node_ip_address()


KEYS_PREFIX = "zswarm-keys-"


def keys_folder() -> Path:
    """A new folder for this actor's keys: mode 0700, named for its pid."""
    return Path(tempfile.mkdtemp(prefix=f"{KEYS_PREFIX}{os.getpid()}-"))


def remove_stale_keys() -> None:
    """Remove the key folders this user's actors left here when they were killed outright."""
    for old in Path(tempfile.gettempdir()).glob(f"{KEYS_PREFIX}*"):
        try:
            pid = int(old.name[len(KEYS_PREFIX):].split("-")[0])
            if old.stat().st_uid == os.getuid() and not Path(f"/proc/{pid}").exists():
                shutil.rmtree(old, ignore_errors=True)
        except (ValueError, OSError):
            continue


class NodeActor:
    """The driver's hands on one node (methods are called through Ray)."""

    def __init__(self, label: str) -> None:
        self.label = label  # how this node's lines are prefixed
        self.kids = Children()  # the router and the fleet: sessions of their own, dying with this worker
        self.host = LocalHost(self.kids, stderr=subprocess.PIPE)  # this node: the driver sets where it binds
        self.lines: deque[str] = deque(maxlen=10_000)
        self.reported: set[str] = set()
        self.lock = threading.Lock()
        self.keys: Path | None = None  # --secure: this node's own keys and certificates
        remove_stale_keys()

    def info(self) -> dict:
        """What the driver checks before it places anything here."""
        import zswarm

        return {"address": node_address(), "cores": len(os.sched_getaffinity(0)), "hostname": socket.gethostname(),
                "version": zswarm.__version__, "pid": os.getpid()}

    def start_router(self, host: str, join: str | None, extra: Sequence[str] = (), proto: str = "tcp") -> str:
        """This node's router on a free port of ``host``, joined to ``join`` (the first node's router);
        ``proto`` tls with ``extra`` naming its configuration (``--secure``)."""
        self.host.bind = host
        endpoint = self.host.start_router(proto, extra, join)
        self._follow(self.kids.named("router")[-1].proc.stderr, "router")
        return endpoint

    def identities(self, names: Sequence[str]) -> dict[str, str]:
        """Make a key pair here for each name that has none (``router``, ``agent-I``); their public halves,
        for the driver's CA to sign."""
        from zswarm.net.certs import make_keys

        if self.keys is None:
            self.keys = keys_folder()
        return make_keys(self.keys, names)

    def install(self, ca_pem: str, certs: dict[str, str], acl: dict) -> str:
        """Keep the certificates signed for this node's keys, and a Zenoh config for each (the router's
        with the run's access control ``acl``); the folder that holds them."""
        from zswarm.net.security import install_identities

        install_identities(self.keys, ca_pem, certs, acl)
        return str(self.keys)

    def spawn_agent(self, name: str, args: Sequence[str]) -> int:
        """Fork agent ``name`` with the agent program's arguments (``-m agents`` not included); its pid."""
        fleet = self.host.fleet
        child = self.host.spawn_agent(name, args)
        if self.host.fleet is not fleet:  # a new fleet: its error lines are this node's
            self._follow(self.host.fleet.child.proc.stderr, None)
        return child.pid

    def _follow(self, stream, name: str | None) -> None:
        def read() -> None:
            for raw in stream:
                text = raw.decode(errors="replace").rstrip("\n")
                with self.lock:
                    self.lines.append(f"[{self.label}] {name + ': ' if name else ''}{text}")
        threading.Thread(target=read, daemon=True).start()

    def poll(self) -> dict:
        """The agents that ended since the last poll (name -> exit code, negative for a signal), the
        stderr lines written meanwhile, and the router's exit code (None while it runs)."""
        ended = {}
        for c in self.kids.named("agent"):
            code = c.proc.poll()
            if code is not None and c.name not in self.reported:
                self.reported.add(c.name)
                ended[c.name] = code
        with self.lock:
            lines = list(self.lines)
            self.lines.clear()
        router = next((code for c in self.kids.named("router") if (code := c.proc.poll()) is not None), None)
        return {"ended": ended, "lines": lines, "router": router}

    def signal(self, name: str, sig: int) -> None:
        c = self.kids.get(name)
        if c is not None and c.alive():
            c.proc.send_signal(sig)

    def restart(self, name: str) -> None:
        """Forget that ``name`` ended (it is about to be spawned again: the new process takes the dead
        one's place among the children)."""
        self.reported.discard(name)

    def stop(self, grace: float = 5.0) -> None:
        """Agents, then the router; every child reaped."""
        self.kids.stop_all(grace)
        if self.keys is not None:
            shutil.rmtree(self.keys, ignore_errors=True)
        if self.host.fleet is not None and self.host.fleet.child.proc.stdin:
            try:
                self.host.fleet.child.proc.stdin.close()
            except OSError:
                pass
