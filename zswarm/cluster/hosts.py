"""The driver's side of each node: a pinned :class:`~zswarm.cluster.node.NodeActor` actor, a host of the
run (:class:`zswarm.host.local.Host`) whose agents are handles with ``subprocess.Popen``'s
interface, so that the supervisor, the chaos and the ending code treat an agent on another machine as
they treat one forked here.

A thread polls each node every 0.2 s for the agents that ended and the lines they wrote; a node that
Ray reports lost (``RayActorError``) has its agents recorded as crashed (exit -9) in one line.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from typing import Any, Callable, Sequence

from zswarm.cluster.node import NodeActor
from zswarm.cluster.ray_cluster import import_ray
from zswarm.args import id_ranges
from zswarm.host.procs import Child, ForkedProc

POLL_S = 0.2
CALL_TIMEOUT_S = 30.0


class RemoteProc(ForkedProc):
    """An agent on a node, behind the part of ``subprocess.Popen`` the supervisor uses (a forked agent's
    handle whose signals go through the node's actor, and whose exit the node's poll reports)."""

    def __init__(self, name: str, pid: int, node: NodeLink) -> None:
        super().__init__(pid)
        self.name, self.node = name, node

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            self.node.signal(self.name, sig)

    def exited(self, code: int) -> None:
        if self.returncode is None:  # the first word wins: a lost node's -9, or the exit the poll saw
            super().exited(code)


class NodeLink:
    """One node: its actor, its agents, and the thread that polls it."""

    def __init__(self, node: dict, label: str, say: Callable[[str], None]) -> None:
        ray = import_ray()
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        self.node_id, self.label, self.say = node["NodeID"], label, say
        self.cpus = int(node.get("Resources", {}).get("CPU", 1))
        strategy = NodeAffinitySchedulingStrategy(node_id=self.node_id, soft=False)
        self.actor = ray.remote(NodeActor).options(num_cpus=0, scheduling_strategy=strategy).remote(label)
        self.procs: dict[str, RemoteProc] = {}
        self.lost = False
        self.closed = False
        self.crashed: list[int] = []  # the agents that were running when the node was lost
        self.router_exit: int | None = None  # the node's router's exit code, once it died
        self.info: dict[str, Any] = {}
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def call(self, method: str, *args: Any, timeout: float = CALL_TIMEOUT_S) -> Any:
        ray = import_ray()
        return ray.get(getattr(self.actor, method).remote(*args), timeout=timeout)

    def hello(self) -> dict:
        self.info = self.call("info", timeout=120.0)  # the first call waits for the actor's worker to start
        return self.info

    def spawn_agent(self, name: str, args: Sequence[str]) -> Child:
        """:meth:`zswarm.host.local.Host.spawn_agent`: forked on the node by its actor (a restarted
        agent's old entry there is dropped first)."""
        self.call("restart", name)
        pid = self.call("spawn_agent", name, list(args))
        proc = self.procs[name] = RemoteProc(name, pid, self)
        return Child(name, proc)

    def signal(self, name: str, sig: int) -> None:
        if not self.lost:
            self.actor.signal.remote(name, sig)  # no wait: the poll reports the exit

    def watch(self) -> None:
        self._thread = threading.Thread(target=self._poll, daemon=True, name=f"poll-{self.label}")
        self._thread.start()

    def _poll(self) -> None:
        ray = import_ray()
        unanswered = 0
        while not self._stop.is_set():
            try:
                report = self.call("poll", timeout=10.0)
                unanswered = 0
            except ray.exceptions.RayActorError as exc:  # Ray says the actor, or its node, is gone
                self._lose(type(exc).__name__)
                return
            except ray.exceptions.GetTimeoutError:  # a node too busy to answer is not lost: 30 s of it is
                unanswered += 1
                if unanswered >= 3:
                    self._lose("no answer for 30 s")
                    return
                continue
            except Exception:  # the driver is shutting Ray down
                return
            for line in report["lines"]:
                print(line, file=sys.stderr, flush=True)
            if report.get("router") is not None and self.router_exit is None:
                self.router_exit = report["router"]
            for name, code in report["ended"].items():
                if name in self.procs:
                    self.procs[name].exited(code)
            self._stop.wait(POLL_S)

    def _lose(self, why: str) -> None:
        self.lost = True
        crashed = sorted(int(n.split("-")[1]) for n, p in self.procs.items() if p.returncode is None)
        self.crashed = crashed
        for p in self.procs.values():
            p.exited(-signal.SIGKILL)
        if crashed:
            self.say(f"node {self.label} lost ({why}): agents {id_ranges(crashed)} crashed; the others carry on")
        else:
            self.say(f"node {self.label} lost ({why})")

    def close(self, grace: float = 5.0) -> None:
        """Stop the node's processes and its actor (once)."""
        if self.closed:
            return
        self.closed = True
        self._stop.set()
        ray = import_ray()
        if not self.lost:
            try:
                self.call("stop", grace, timeout=grace + 15.0)
            except Exception:
                pass
        try:
            ray.kill(self.actor)
        except Exception:
            pass
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline and any(p.returncode is None for p in self.procs.values()):
            time.sleep(0.05)
