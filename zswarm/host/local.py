"""The host boundary: what starts a run's processes (routers, the world, agents) and where.

A host hands back a :class:`~zswarm.host.procs.Child`, whose handle has the part of
``subprocess.Popen``'s interface that supervision uses (``poll``, ``wait``, ``send_signal``, ``kill``).
The supervisor, the chaos schedule and the ending code see only that, so they do not know where a
process runs: :class:`LocalHost` is this machine (each agent forked from one fleet, or a fresh
interpreter each), and :class:`zswarm.cluster.hosts.NodeLink` is a node of a Ray cluster, whose actor
runs a :class:`LocalHost` there. Each router's address comes from its host's bind address
(:data:`zswarm.ports.LOOPBACK` unless the user gives one), never from a literal.
"""

from __future__ import annotations

import subprocess
from typing import TYPE_CHECKING, Protocol, Sequence

from zswarm.host.procs import Child, Children, Fleet, free_port, start_mesh, start_router, world_argv
from zswarm.ports import LOOPBACK

if TYPE_CHECKING:
    from zswarm.net.runspec import RunSpec


class Host(Protocol):
    label: str

    def spawn_agent(self, name: str, args: Sequence[str]) -> Child:
        """Start agent ``name`` with the agent program's arguments (``python -m agents`` not included)."""
        ...


class LocalHost:
    """This machine: its routers listen on ``bind``, its agents are forked from one fleet (``fork``) or
    each started in a fresh interpreter; every process joins ``kids``. ``stderr``: where the routers'
    and the fleet's error output goes (None: this process's; a Ray node's actor reads it from a pipe)."""

    label = "local"

    def __init__(self, kids: Children, fork: bool = True, bind: str = LOOPBACK, stderr: int | None = None) -> None:
        self.kids, self.fork, self.bind, self.stderr = kids, fork, bind, stderr
        self.fleet: Fleet | None = None

    def endpoint(self, proto: str = "tcp") -> str:
        """A router endpoint on a free port of this host's bind address."""
        host = f"[{self.bind}]" if ":" in self.bind else self.bind
        return f"{proto}/{host}:{free_port(self.bind)}"

    def start_routers(self, endpoints: Sequence[str], join: str | None = None, extra: Sequence[str] = (),
                      each: Sequence[Sequence[str]] | None = None) -> list[str]:
        """Routers on ``endpoints``, meshed (the first joins ``join``, each other the first), once each
        accepts connections (``extra``: every router's arguments, ``each``: each one's own); RuntimeError
        if one does not."""
        start_mesh(self.kids, endpoints, join, extra, each)
        return list(endpoints)

    def start_router(self, proto: str = "tcp", extra: Sequence[str] = (), join: str | None = None) -> str:
        """One router on a free port of the bind address (``extra``: router arguments), joined to the
        router ``join`` if given, once it accepts connections (and has joined); its endpoint."""
        return start_router(self.kids, self.bind, proto=proto, extra=extra, name="router", stderr=self.stderr,
                            join=join)

    def spawn_world(self, spec: RunSpec, connect: str, *extra: str, stdout: int | None = subprocess.DEVNULL,
                    name: str = "world") -> Child:
        """The world of ``spec``, connected to ``connect``; ``extra``: world options."""
        return self.kids.spawn(name, world_argv(spec, connect, *extra), stdout=stdout)

    def spawn_agent(self, name: str, args: Sequence[str]) -> Child:
        if not self.fork:
            return self.kids.spawn(name, ["-m", "agents", *args], stdout=subprocess.DEVNULL)
        if self.fleet is None or not self.fleet.child.alive():
            self.fleet = Fleet(self.kids, stderr=self.stderr)
        return self.fleet.spawn(name, args)
