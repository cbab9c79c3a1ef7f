"""Where a run's agents run: the boundary between supervising a run and starting its processes.

A host starts one agent process from the agent program's arguments and hands back a
:class:`~zswarm.net.procs.Child`, whose handle has the part of ``subprocess.Popen``'s interface that
supervision uses (``poll``, ``wait``, ``send_signal``, ``kill``). The supervisor, the chaos schedule
and the ending code see only that, so they do not know where a process runs: :class:`LocalHost` is
this machine (each agent forked from one fleet, or a fresh interpreter each), and
:class:`zswarm.cluster.hosts.NodeLink` is a node of a Ray cluster (its agents forked there by the
node's actor).
"""

from __future__ import annotations

import subprocess
from typing import Protocol, Sequence

from zswarm.net.procs import Child, Children, Fleet


class Host(Protocol):
    label: str

    def spawn_agent(self, name: str, args: Sequence[str]) -> Child:
        """Start agent ``name`` with the agent program's arguments (``python -m agents`` not included)."""
        ...


class LocalHost:
    """This machine: agents forked from one fleet (``fork``), or each in a fresh interpreter; every
    process joins ``kids``."""

    label = "local"

    def __init__(self, kids: Children, fork: bool = True) -> None:
        self.kids, self.fork = kids, fork
        self.fleet: Fleet | None = None

    def spawn_agent(self, name: str, args: Sequence[str]) -> Child:
        if not self.fork:
            return self.kids.spawn(name, ["-m", "agents", *args], stdout=subprocess.DEVNULL)
        if self.fleet is None:
            self.fleet = Fleet(self.kids)
        return self.fleet.spawn(name, args)
