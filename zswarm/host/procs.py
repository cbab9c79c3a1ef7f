"""Child processes that never outlive their parent: spawn, stop in order, always reap.

Every child gets ``PR_SET_PDEATHSIG`` (SIGTERM when the parent dies, even by SIGKILL) and its own
session, so a terminal's Ctrl-C reaches only the launcher, which then stops the children in order
(agents, then the world, which flushes its recording, then the router).
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
from dataclasses import dataclass, field
from typing import IO, TYPE_CHECKING, Sequence

from zswarm.ports import LOOPBACK, free_port, local_host, port_in_use  # noqa: F401  (re-exported: the launcher,
# benchmarks and tests take them here)
from zswarm.net.security import router_name
from zswarm.process import die_with_parent, one_blas_thread

if TYPE_CHECKING:
    from zswarm.net.runspec import RunSpec


def python_env() -> dict[str, str]:
    """The children run the installed modules (``python -m world``, ``-m agents``) with this Python."""
    env = dict(os.environ)
    env.setdefault("PYTHONUNBUFFERED", "1")
    one_blas_thread(env)
    return env


@dataclass
class Child:
    name: str
    proc: subprocess.Popen | ForkedProc

    @property
    def pid(self) -> int:
        return self.proc.pid

    def alive(self) -> bool:
        return self.proc.poll() is None


@dataclass
class Children:
    """A set of named child processes, stopped and reaped together. A child added under the name of a
    dead one takes its place (a restart); beside a live one of its name (two routers a test starts,
    say) both are kept, and :meth:`get` finds the newer."""

    children: list[Child] = field(default_factory=list)
    _by_name: dict[str, Child] = field(default_factory=dict, repr=False)

    def add(self, child: Child) -> Child:
        """Take ``child`` in (again: a no-op), in place of a dead child of its name, in constant time
        (a launcher adds a thousand agents)."""
        held = self._by_name.get(child.name)
        if held is child:
            return child
        if held is not None and not held.alive():
            self.children.remove(held)  # a restart: rare, and only then a pass over the list
        self._by_name[child.name] = child
        self.children.append(child)
        return child

    def get(self, name: str) -> Child | None:
        return self._by_name.get(name)

    def spawn(self, name: str, args: Sequence[str], stdout: int | IO | None = None,
              stderr: int | IO | None = None, stdin: int | IO | None = subprocess.DEVNULL,
              new_session: bool = True) -> Child:
        """``new_session``: the child in a session of its own (a terminal's Ctrl-C reaches only the
        launcher; under Linux's autogroup scheduling a session is also the unit that shares the CPU,
        which is why a router and a fleet always get one: ``agents.fleet``)."""
        proc = subprocess.Popen([sys.executable, *args], env=python_env(),
                                stdout=stdout, stderr=stderr, stdin=stdin,
                                preexec_fn=die_with_parent, start_new_session=new_session)
        return self.add(Child(name, proc))

    def named(self, prefix: str) -> list[Child]:
        return [c for c in self.children if c.name.startswith(prefix)]

    @staticmethod
    def stop(children: Sequence[Child], grace: float, sig: int = signal.SIGTERM) -> None:
        """Signal, wait up to ``grace`` seconds, then SIGKILL whoever is left; always reap."""
        for c in children:
            if c.alive():
                try:
                    c.proc.send_signal(sig)
                    c.proc.send_signal(signal.SIGCONT)  # a frozen (SIGSTOPped) child must see it too
                except ProcessLookupError:
                    pass
        deadline = time.monotonic() + grace
        for c in children:
            try:
                c.proc.wait(timeout=max(deadline - time.monotonic(), 0.01))
            except subprocess.TimeoutExpired:
                c.proc.kill()
                try:
                    c.proc.wait(timeout=10.0)
                except subprocess.TimeoutExpired:  # a forked agent whose fleet is stuck: it dies with it
                    pass

    def stop_all(self, grace: float = 5.0) -> None:
        """Agents first, then the world (it flushes), then everything else (the router)."""
        self.stop(self.named("agent"), grace)
        self.stop(self.named("world"), max(grace, 10.0))
        self.stop([c for c in self.children if c.alive()], grace)


class ForkedProc:
    """An agent the fleet forked (``python -m agents.fleet``), behind the part of ``subprocess.Popen``'s
    interface :class:`Children` uses; its exit status comes from the fleet."""

    stdout = None

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.returncode: int | None = None
        self._done = threading.Event()

    def poll(self) -> int | None:
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if not self._done.wait(timeout):
            raise subprocess.TimeoutExpired(f"agent pid {self.pid}", timeout or 0.0)
        return self.returncode  # type: ignore[return-value]

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:
                pass

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def exited(self, code: int) -> None:
        self.returncode = code
        self._done.set()


class Fleet:
    """One ``python -m agents.fleet`` child that imports the agent program once and forks each agent
    from itself (shared pages, a start in milliseconds); each agent is still its own process."""

    def __init__(self, kids: Children, stderr: int | None = None) -> None:
        self.kids = kids
        # a session of its own: its agents are then one scheduling group under Linux's autogroup
        # (agents.fleet), beside the router's, not threads among a Ray worker's
        self.child = kids.spawn("fleet", ["-m", "agents.fleet"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                stderr=stderr)
        self.procs: dict[str, ForkedProc] = {}
        self.started: dict[str, threading.Event] = {}
        self.lock = threading.Lock()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        for raw in self.child.proc.stdout:
            verb, name, value = (raw.decode().split() + ["", "", ""])[:3]
            with self.lock:
                if verb == "pid":
                    self.procs[name] = ForkedProc(int(value))
                    self.started.setdefault(name, threading.Event()).set()
                elif verb == "exit" and name in self.procs:
                    self.procs[name].exited(int(value))
        with self.lock:  # the fleet is gone, and its agents with it
            for proc in self.procs.values():
                if proc.returncode is None:
                    proc.exited(-signal.SIGKILL)
            for event in self.started.values():
                event.set()

    def spawn(self, name: str, args: Sequence[str], timeout: float = 60.0) -> Child:
        """Fork agent ``name`` with the agent program's arguments ``args`` (``-m agents`` not included)."""
        with self.lock:
            event = self.started[name] = threading.Event()
            self.procs.pop(name, None)
        self.child.proc.stdin.write(f"spawn {name} {json.dumps(list(args))}\n".encode())
        self.child.proc.stdin.flush()
        if not event.wait(timeout) or name not in self.procs:
            raise RuntimeError(f"the agent fleet did not start {name} (it exited with {self.child.proc.poll()})")
        return self.kids.add(Child(name, self.procs[name]))


def wait_for_port(host: str, port: int, timeout: float, child: Child | None = None) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if port_in_use(host, port):
            return True
        if child is not None and not child.alive():
            return False
        time.sleep(0.05)
    return False


def start_router(kids: Children, host: str = LOOPBACK, proto: str = "tcp", extra: Sequence[str] = (),
                 name: str = "router", stderr: int | None = None, join: str | None = None) -> str:
    """A router child listening on a free port of ``host`` (``extra``: more router arguments, e.g.
    ``--config``), joined to the router ``join`` if given; returns its endpoint once the port accepts
    connections (and it has joined: RuntimeError if it cannot)."""
    endpoint = f"{proto}/{host}:{free_port(host)}"
    _spawn_router(kids, name, endpoint, join, extra, stderr)
    return endpoint


ROUTER_MODULE = "zswarm.net.router"


def start_mesh(kids: Children, endpoints: Sequence[str], join: str | None = None, extra: Sequence[str] = (),
               each: Sequence[Sequence[str]] | None = None) -> None:
    """Routers listening on ``endpoints`` (``proto/HOST:PORT``), meshed: the first joins ``join`` (another
    machine's router, if any), every other joins the first (``zswarm run --routers K``). ``extra``: more
    router arguments for every router (``--config``), ``each``: for each router its own (its identity,
    under ``--secure``). Returns once each accepts connections; RuntimeError if one does not."""
    for k, endpoint in enumerate(endpoints):
        _spawn_router(kids, router_name(k), endpoint, endpoints[0] if k > 0 else join,
                      [*extra, *(each[k] if each else ())])


def _spawn_router(kids: Children, name: str, endpoint: str, join: str | None, extra: Sequence[str],
                  stderr: int | None = None) -> Child:
    """One router on ``endpoint`` (joining ``join``), once it accepts connections. It is a session of its
    own: with Linux's autogroup scheduling a session is the unit that shares the CPU, and a router that
    shared one with a node's agents competed with them thread by thread (``agents.fleet`` says what a
    starved router did to a swarm)."""
    router = kids.spawn(name, ["-m", ROUTER_MODULE, "--listen", endpoint, *(["--connect", join] if join else []),
                               *extra], stdout=subprocess.PIPE if join else subprocess.DEVNULL, stderr=stderr)
    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    if not wait_for_port(local_host(host.strip("[]")), int(port), 10.0, router):
        raise RuntimeError(f"the router did not start on {endpoint} (port taken? address not local?)")
    if join and not _says_ready(router, JOIN_WAIT_S):
        from zswarm.net.router import JOIN_HINT

        raise RuntimeError(f"the router on {endpoint} could not join {join}: {JOIN_HINT}")
    return router


#: How long a router that joins another is given to say it has (it gives up itself after its
#: ``--connect-timeout``, 15 s by default).
JOIN_WAIT_S = 40.0


def _says_ready(router: Child, seconds: float) -> bool:
    """Whether the router's first line says it is ready (it exits without one when it cannot join)."""
    from zswarm.net.router import READY

    sel = selectors.DefaultSelector()
    sel.register(router.proc.stdout, selectors.EVENT_READ)
    deadline = time.monotonic() + seconds
    try:
        while time.monotonic() < deadline:
            if sel.select(timeout=0.2):
                return router.proc.stdout.readline().decode(errors="replace").startswith(READY)
            if not router.alive():
                return False
        return False
    finally:
        sel.close()


def world_argv(spec: RunSpec, connect: str, *extra: str) -> list[str]:
    """The world's command line (after the interpreter) for ``spec``; ``extra``: world options."""
    return ["-m", "world", *spec.to_argv(), "--connect", connect, *extra]


def agent_argv(spec: RunSpec, agent: int, connect: str, *extra: str) -> list[str]:
    """Agent ``agent``'s command line (after the interpreter) for ``spec``."""
    return ["-m", "agents", "--id", str(agent), *spec.to_argv(), "--connect", connect, *extra]
