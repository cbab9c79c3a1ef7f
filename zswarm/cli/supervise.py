"""A launched run, from the first child to the last reaped: start, supervise, stage the chaos, end.

:class:`Launch` holds the run's state (its children, the current world, what chaos has done) in its
own fields; the plan it carries out is the checked, immutable :class:`~zswarm.cli.launch.Plan`.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time

import numpy as np

from zswarm.args import UsageError
from zswarm.cli.chaos import Event, schedule
from zswarm.cli.launch import Plan, endpoint_host_port
from zswarm.net.procs import (
    ROUTER_MODULE,
    Child,
    Children,
    Fleet,
    agent_argv,
    free_port,
    port_in_use,
    wait_for_port,
    world_argv,
)


def _say(text: str, err: bool = True) -> None:
    print(f"launch: {text}", file=sys.stderr if err else sys.stdout, flush=True)


class Launch:
    def __init__(self, plan: Plan) -> None:
        self.plan, self.spec = plan, plan.spec
        self.kids = Children()
        self.world: Child | None = None
        self.world_started = threading.Event()  # the current world's clock is running
        self.world_down = False  # killed, and a replacement is scheduled
        self.started_at = time.time()
        self.endpoint = plan.connect  # the first router's: the world's, and agent i's on router i mod K
        self.endpoints: list[str] = []
        self.configs: dict[str, list[str]] = {}
        self.fleet: Fleet | None = None
        self.pending: list[Event] = schedule(plan.kill, plan.restart_after, plan.world_outage, plan.world_crash)
        self.rng = np.random.default_rng([self.spec.seed, 0xC0FFEE])
        self.killed: list[int] = []
        self.expected_exits: set[str] = set()  # children chaos killed on purpose
        self.spawned_viewer: str | None = None  # the URL of the viewer --spawn started
        self.crashed: set[str] = set()
        self.world_crash_for_good = plan.world_crash is not None and plan.world_crash[1] is None

    # --- start ----------------------------------------------------------------------------------------

    def run(self) -> int:
        self.configs = self._zenoh_configs()
        if "router" in self.plan.roles:
            self.endpoint = self.plan.listen or f"{'tls' if self.plan.secure else 'tcp'}/127.0.0.1:{free_port()}"
            host, port = endpoint_host_port(self.endpoint)
            if port_in_use(_local(host), port):
                raise UsageError(f"port {port} on {host} is already in use; pick another with --listen")
        interrupted = False

        def on_sigterm(_signum: int, _frame: object) -> None:
            nonlocal interrupted
            interrupted = True
            raise KeyboardInterrupt

        signal.signal(signal.SIGTERM, on_sigterm)
        try:
            self._start()
            return self._supervise()
        except KeyboardInterrupt:
            _say("stopping (agents, then the world, then the router)")
            self.kids.stop_all()
            self._finish_recording(None)
            return 143 if interrupted else 130
        finally:
            self.kids.stop_all()

    def _start(self) -> None:
        plan = self.plan
        self.endpoints = [self.endpoint]
        if "router" in plan.roles:
            proto = self.endpoint.split("/", 1)[0]
            self.endpoints += [f"{proto}/127.0.0.1:{free_port()}" for _ in range(plan.routers - 1)]
            for k, endpoint in enumerate(self.endpoints):
                joins = self.endpoints[0] if k > 0 else plan.connect  # the others join the first
                router = self.kids.spawn("router" if k == 0 else f"router-{k}",
                                         ["-m", ROUTER_MODULE, "--listen", endpoint,
                                          *(["--connect", joins] if joins else []), *self.configs.get("router", [])],
                                         stdout=subprocess.DEVNULL)
                host, port = endpoint_host_port(endpoint)
                if not wait_for_port(_local(host), port, 10.0, router):
                    raise UsageError(f"the router did not start on {endpoint} (port taken? address not local?)")
        if "world" in plan.roles:
            self._spawn_world(resume=False)
        if "agents" in plan.roles:
            for i in plan.ids:
                self._spawn_agent(i)
        if not plan.quiet:
            routers = f"router {self.endpoint}" if len(self.endpoints) == 1 else \
                f"{len(self.endpoints)} routers {', '.join(self.endpoints)}"
            _say(f"run {self.spec.run!r}, {len(self.kids.named('agent'))} agent processes, {routers}", err=False)

    def _zenoh_configs(self) -> dict[str, list[str]]:
        """``--config`` arguments by role: --config/--router-config as given, or --secure DIR's files
        (made there if DIR has none: one identity per agent, see :meth:`_agent_config`)."""
        plan = self.plan
        if plan.secure is None:
            out = {}
            if plan.config is not None:
                out["world"] = out["agent"] = ["--config", str(plan.config)]
            if plan.router_config is not None:
                out["router"] = ["--config", str(plan.router_config)]
            return out
        from zswarm.net.security import is_secure_dir, write_secure_dir

        if not is_secure_dir(plan.secure):
            write_secure_dir(plan.secure, agents=self.spec.scenario.n_agents)
            if not plan.quiet:
                _say(f"made a CA, certificates (one per agent) and configs in {plan.secure}", err=False)
        return {role: ["--config", str(plan.secure / f"{role}.json5")] for role in ("router", "world")}

    def _agent_config(self, agent: int) -> list[str]:
        """Agent ``agent``'s config: under --secure, its own identity's if DIR has one."""
        if self.plan.secure is None:
            return self.configs.get("agent", [])
        from zswarm.net.security import agent_config

        return ["--config", str(agent_config(self.plan.secure, agent))]

    def router_of(self, agent: int) -> int:
        return agent % len(self.endpoints)

    def _spawn_agent(self, agent: int) -> None:
        argv = agent_argv(self.spec, agent, self.endpoints[self.router_of(agent)], *self._agent_config(agent))
        if not self.plan.fork:
            self.kids.spawn(f"agent-{agent}", argv, stdout=subprocess.DEVNULL)
            return
        if self.fleet is None:
            self.fleet = Fleet(self.kids)
        self.fleet.spawn(f"agent-{agent}", argv[2:])  # without "-m agents"

    def _viewer(self):
        """The live viewer the world streams to; a --spawn'ed one is started here, once, so that a world
        that is restarted finds the same viewer."""
        from zswarm.record.live import Viewer, spawn_viewer

        if not self.plan.viewer.spawn:
            return self.plan.viewer
        if self.spawned_viewer is None:
            self.spawned_viewer = spawn_viewer()
        return Viewer(connect=self.spawned_viewer, serve=self.plan.viewer.serve)

    def _spawn_world(self, resume: bool) -> None:
        """Start the world (``resume``: a replacement that records into the next segment)."""
        plan = self.plan
        extra = [*self.configs.get("world", []), "--record", str(plan.record), "--summary", str(plan.summary),
                 "--progress", "0" if plan.quiet else "2"]
        if plan.trajectory is not None:
            extra += ["--trajectory", str(plan.trajectory)]
        if resume:
            extra.append("--resume")
        extra += self._viewer().to_argv()
        self.world = self.kids.spawn("world", world_argv(self.spec, self.endpoint, *extra), stdout=subprocess.PIPE)
        self.world_started = threading.Event()
        threading.Thread(target=self._forward, args=(self.world, self.world_started), daemon=True).start()

    def _forward(self, world: Child, started: threading.Event) -> None:
        """Pass the world's lines through, and note when its clock starts."""
        for line in world.proc.stdout:
            text = line.decode(errors="replace") if isinstance(line, bytes) else line
            if text.startswith("world: started"):
                started.set()
            if not self.plan.quiet or text.startswith("world: done"):
                sys.stdout.write(text)
                sys.stdout.flush()

    # --- while it runs --------------------------------------------------------------------------------

    def _supervise(self) -> int:
        """Wait for the world to finish (or, without a world, for the agents / for Ctrl-C)."""
        t0: float | None = None if self.world is not None else time.monotonic()
        while True:
            if t0 is None and self.world_started.is_set():
                t0 = time.monotonic()  # chaos times count from the start of the world's clock
            while t0 is not None and self.pending and time.monotonic() - t0 >= self.pending[0].at:
                self._stage(self.pending.pop(0), time.monotonic() - t0)
            self._note_crashes()
            if self.world is not None and not self.world.alive() and not self.world_down:
                break
            if self.world is None and "agents" in self.plan.roles and not any(
                    c.alive() for c in self.kids.named("agent")):
                return 0
            dead = [c.name for c in self.kids.named("router") if not c.alive()]
            if dead:
                _say(f"the router died ({', '.join(dead)}); stopping the run")
                self.kids.stop_all()
                self._finish_recording(None)
                return 1
            time.sleep(0.1)
        Children.stop(self.kids.named("agent"), 5.0)  # they end on the world's final tick; this reaps them
        code = self.world.proc.returncode
        self._finish_recording(code)
        if self.world_crash_for_good:
            return 0  # the run ended where it was asked to (--world-crash T)
        return 0 if code == 0 else (2 if code == 2 else 1)

    def _note_crashes(self) -> None:
        for c in self.kids.children:
            code = c.proc.poll()
            if (code not in (None, 0) and c.name.startswith("agent") and c.name not in self.crashed
                    and c.name not in self.expected_exits):
                self.crashed.add(c.name)
                _say(f"{c.name} exited with code {code}; the others carry on")

    def _stage(self, event: Event, t: float) -> None:
        """Carry out one scheduled event (world events only where this machine runs the world)."""
        world = self.world
        if event.action == "kill_agents":
            alive = [c for c in self.kids.named("agent") if c.alive()]
            chosen = self.rng.choice(len(alive), size=min(event.count, len(alive)), replace=False)
            for k in sorted(chosen):
                alive[k].proc.kill()
                self.expected_exits.add(alive[k].name)
                self.killed.append(int(alive[k].name.split("-")[1]))
            _say(f"killed agents {sorted(self.killed)} at {t:.1f} s")
        elif event.action == "restart_agents":
            for i in self.killed:
                self._spawn_agent(i)
            _say(f"restarted agents {sorted(self.killed)} at {t:.1f} s")
        elif world is None:
            return
        elif event.action == "kill_world":
            world.proc.kill()
            world.proc.wait()
            self.world_down = any(e.action == "resume_world" for e in self.pending)
            _say(f"killed the world at {t:.1f} s")
        elif event.action == "resume_world":
            self._spawn_world(resume=True)
            self.world_down = False
            _say(f"started a new world at {t:.1f} s (--resume)")
        elif event.action == "freeze_world":
            world.proc.send_signal(signal.SIGSTOP)
            _say(f"world frozen at {t:.1f} s")
        elif event.action == "thaw_world":
            world.proc.send_signal(signal.SIGCONT)
            _say(f"world resumed at {t:.1f} s")

    # --- end ------------------------------------------------------------------------------------------

    def _finish_recording(self, code: int | None) -> None:
        """Every run ends with a recording and a summary: a world that wrote its summary gets the
        reference simulation beside it; one that died without has its recording repaired and the
        summary recomputed from it."""
        plan, world = self.plan, self.world
        if "world" not in plan.roles or world is None or world.alive():
            return
        fresh = plan.summary.exists() and plan.summary.stat().st_mtime >= self.started_at
        if fresh and world.proc.returncode == 0:
            from zswarm.cli.reference import add_reference

            add_reference(plan.summary, self.spec, {
                "routers": self.endpoints,
                "agent_router": {str(i): self.router_of(i) for i in plan.ids} if "agents" in plan.roles else {}})
        elif world.proc.returncode != 2 and plan.record.exists():
            from zswarm.record.salvage import salvage_summary

            try:
                salvage_summary(plan.record, plan.summary)
                _say(f"the world ended with code {world.proc.returncode}; its recording was made whole and "
                     f"the summary recomputed from it (\"salvaged\": true)")
            except UsageError as exc:
                _say(f"the world ended with code {world.proc.returncode} and its recording cannot be "
                     f"salvaged: {exc}")
        if not plan.quiet and plan.record.exists():
            _say(f"recording {plan.record} (open with: rerun {plan.record}); summary {plan.summary}", err=False)


def _local(host: str) -> str:
    """Where to check a listening port: a wildcard address is reached on loopback."""
    return "127.0.0.1" if host in ("0.0.0.0", "::") else host
