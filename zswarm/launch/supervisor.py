"""A launched run, from the first child to the last reaped: start, supervise, stage the chaos, end.

:class:`Launch` holds the run's state (its children, the current world, what chaos has done) in its
own fields; the plan it carries out is the checked, immutable :class:`~zswarm.launch.plan.Plan`.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from zswarm.laws.bound import EXIT_LAW_FAILED
from zswarm.errors import UsageError
from zswarm.launch.chaos import FAULT_STARTS, Event, schedule
from zswarm.launch.configs import agent_config_args, role_configs
from zswarm.launch.ending import finish_recording
from zswarm.launch.local_runs import announce, forget
from zswarm.host.local import Host, LocalHost
from zswarm.ports import LOOPBACK
from zswarm.launch.migration import Migration
from zswarm.launch.placement import place
from zswarm.args import id_ranges
from zswarm.launch.plan import Plan
from zswarm.net.config import CONNECT_TIMEOUT, endpoint_host_port, unreachable
from zswarm.launch.world_lines import DONE, forward_lines
from zswarm.launch.world_watch import WorldWatch
from zswarm.host.procs import (
    Child,
    Children,
    agent_argv,
    local_host,
    port_in_use,
    wait_for_port,
)

#: No agent is moved (--migrate-every) in the run's last MOVE_WALL_S wall seconds (or its last simulated
#: second): a taker process started then, on a loaded machine, may not have the agent when the run ends.
MOVE_WALL_S = 3.0


#: How long a world waits for its agents: 30 s, and 0.1 s more per agent (a large swarm forks its
#: agents one by one on a loaded machine: 500 took about a minute on 2 cores).
def world_start_timeout(n_agents: int) -> float:
    return 30.0 + 0.1 * n_agents


def _say(text: str, err: bool = True) -> None:
    print(f"launch: {text}", file=sys.stderr if err else sys.stdout, flush=True)


class Launch:
    def __init__(self, plan: Plan) -> None:
        self.plan, self.spec = plan, plan.spec
        self.kids = Children()
        self.world: Child | None = None
        self.world_started = threading.Event()  # the world's clock is running (heard on Zenoh)
        self.world_down = False  # killed, and a replacement is scheduled
        self.started_at = time.time()
        self.endpoint = plan.connect  # the first router's: the world's, and agent i's on router i mod K
        self.endpoints: list[str] = []
        self.announced: Path | None = None  # this run's entry among the local runs (zswarm.launch.local_runs)
        self.configs: dict[str, list[str]] = {}
        # this machine: its routers bind where --listen says (loopback by default), its agents fork here
        self.local = LocalHost(self.kids, plan.fork, endpoint_host_port(plan.listen)[0] if plan.listen else LOOPBACK)
        self.watch: WorldWatch | None = None  # with chaos to time: the world's start, heard on Zenoh
        self.pending: list[Event] = schedule(plan.kill, plan.restart_after, world_crash=plan.world_crash,
                                             pauses=plan.pauses)
        self.staged: list[dict] = []  # each fault as it was staged, for the summary
        self.paused: dict[str, Child] = {}  # frozen now, by name: each is let go at its time (and by any stop)
        self.began: dict[str, float] = {}  # a fault started, by what it names: the wall seconds it began late
        self.rng = np.random.default_rng([self.spec.seed, 0xC0FFEE])
        self.killed: list[int] = []
        self.expected_exits: set[str] = set()  # children chaos killed on purpose
        self.spawned_viewer: str | None = None  # the URL of the viewer --spawn started
        self.crashed: set[str] = set()
        self.world_crash_for_good = plan.world_crash is not None and plan.world_crash[1] is None
        # --migrate-every: where each agent runs now, its newest process and the one it replaces
        self.migration = Migration(plan.migrate_every) if plan.migrate_every else None
        self.where: dict[int, int] = {}
        self.current: dict[int, Child] = {}
        self.leaving: dict[int, Child] = {}

    # --- start ----------------------------------------------------------------------------------------

    def run(self) -> int:
        self.configs = role_configs(self.plan, self.spec.scenario.n_agents, _say)
        if "router" in self.plan.roles:
            self.endpoint = self.plan.listen or self.local.endpoint("tls" if self.plan.secure else "tcp")
            host, port = endpoint_host_port(self.endpoint)
            if port_in_use(local_host(host), port):
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
            self._finish_recording()
            return 143 if interrupted else 130
        finally:
            self.kids.stop_all()
            forget(self.announced)
            if self.watch is not None:
                self.watch.close()

    def _start(self) -> None:
        """The routers (:meth:`_start_routers`), the world, then the agents, each on its host."""
        plan = self.plan
        self._start_routers()
        if "world" in plan.roles:
            self._spawn_world(resume=False)
        if self.migration is not None and not self.where:  # agents start placed by space over the routers
            spawns = self.spec.scenario.initial_positions(np.random.default_rng(self.spec.seed))[list(plan.ids)]
            self.where = dict(zip(plan.ids, place(spawns, self.capacities(), "space")))
        if (self.pending or self.migration is not None) and ("world" in plan.roles or "agents" in plan.roles):
            self._watch_world()
        if "agents" in plan.roles:
            for k, i in enumerate(plan.ids):
                if self.world is not None and not self.world.alive():  # the run is over: start no more
                    _say(f"the world ended before every agent started ({k} of {len(plan.ids)} started): "
                         "fewer agents, or a slower --time-scale, let this machine start them in time")
                    break
                self._spawn_agent(i)
        if not plan.quiet:
            _say(self._started(), err=False)
            if self.announced is not None:
                from zswarm.launch.ending import installed_command

                _say(f"watch it live: {installed_command('zswarm')} monitor --run {self.spec.run}", err=False)
            for note in plan.notes:
                _say(note, err=False)

    def _monitor_config(self) -> Path | None:
        """The Zenoh config ``zswarm monitor --run`` joins this run with: the world's (an identity that may
        watch it under --secure), or the one given with --config; None for an open run."""
        return self.plan.secure / "world.json5" if self.plan.secure is not None else self.plan.config

    def _start_routers(self) -> None:
        """This machine's routers (``--routers K`` meshed, joined to ``--connect``), or, on a machine
        started by hand without one, the other machine's router reached."""
        plan = self.plan
        self.endpoints = [self.endpoint]
        if plan.connect is not None:  # the other machine's router (to use, or to join) answers, or one line
            self._reach_router(plan.connect)
        if "router" not in plan.roles:  # a machine started by hand: its router is another machine's
            return
        proto = self.endpoint.split("/", 1)[0]
        self.endpoints += [self.local.endpoint(proto) for _ in range(plan.routers - 1)]
        try:
            self.local.start_routers(self.endpoints, plan.connect, self.configs.get("router", []),
                                     self.configs.get("routers"))
        except RuntimeError as exc:
            raise UsageError(str(exc)) from None
        self.announced = announce(self.spec.run, self.endpoint, self._monitor_config())  # zswarm monitor --run finds it

    def _started(self) -> str:
        """The line that says the run has started, and where."""
        routers = f"router {self.endpoint}" if len(self.endpoints) == 1 else \
            f"{len(self.endpoints)} routers {', '.join(self.endpoints)}"
        return f"run {self.spec.run!r}, {len(self.kids.named('agent'))} agent processes, {routers}"

    def _watch_world(self) -> None:
        """Chaos counts from the world's start, heard on Zenoh (beside the world as on another machine),
        over the world's identity where the world runs here, else the agents'."""
        args = self.configs.get("world", []) if "world" in self.plan.roles else self._agent_config(self.plan.ids[0])
        config = Path(args[args.index("--config") + 1]) if "--config" in args else None
        timeout = self.plan.connect_timeout if self.plan.connect_timeout is not None else 15.0
        self.watch = WorldWatch(self.spec.keys, self.endpoint, config, timeout,
                                 tick_dt=self.spec.scenario.dt if self.spec.clock == "lockstep" else None)
        self.world_started = self.watch.started
        if self.world is None and not self.plan.quiet:
            _say("faults are timed from the world's start, when this machine hears it", err=False)

    def _agent_config(self, agent: int) -> list[str]:
        return agent_config_args(self.plan, self.configs, agent)

    def router_of(self, agent: int) -> int:
        return self.where.get(agent, agent % len(self.endpoints))

    def _moved(self, agent: int, router: int) -> None:
        """Agent ``agent`` runs on router (node) ``router`` from now on."""
        self.where[agent] = router

    def capacities(self) -> list[float]:
        """How many agents each router (node) takes, relatively."""
        return [1.0] * len(self.endpoints)

    def host_of(self, agent: int) -> Host | None:
        """Where agent ``agent`` runs (None: nowhere left to run it)."""
        return self.local

    def _spawn_agent(self, agent: int) -> None:
        """Start (or restart: it replaces its dead self among the children) agent ``agent`` on its host."""
        host = self.host_of(agent)
        if host is None:
            _say(f"agent {agent}: no host left to run it on")
            return
        router = self.router_of(agent)
        movable = ["--movable"] if self.migration is not None else []
        argv = agent_argv(self.spec, agent, self.endpoints[router], "--node", str(router), *movable,
                          *self._agent_config(agent))
        self.current[agent] = self.kids.add(host.spawn_agent(f"agent-{agent}", argv[2:]))  # without "-m agents"

    def _migrate(self, t: float) -> None:
        """Move the agents whose node the swarm's new split changes (:mod:`zswarm.launch.migration`)."""
        from zswarm.net import messages as msg

        try:
            seen = self.watch.positions(self.spec.keys.positions)
        except msg.DecodeError as exc:
            _say(f"migration skipped at t = {t:.1f} s: {exc}")
            seen = None
        if seen is None:
            if self.migration.unanswered == 0:
                _say(f"migration: the world did not say where its agents are at t = {t:.1f} s; each look "
                     "tries again (the summary counts looks_unanswered)")
            self.migration.unanswered += 1
            self.migration.next_at = t + self.migration.every
            return
        # still handing over, or its process is gone (crashed: the restart, if any, brings it back)
        busy = {i for i, c in self.leaving.items() if c.alive()} | {i for i, c in self.current.items() if not c.alive()}
        _, ids, positions = seen
        moves = self.migration.plan(t, ids, positions, {i: self.router_of(i) for i in self.current},
                                    self.capacities(), busy)
        for agent, was, to, position in moves:
            self._moved(agent, to)
            host = self.host_of(agent)
            if host is None:
                self._moved(agent, was)
                continue
            to = self.router_of(agent)  # the host may have placed it elsewhere (a node lost meanwhile)
            n = self.migration.moved[agent]
            start = ",".join(repr(float(c)) for c in position)
            argv = agent_argv(self.spec, agent, self.endpoints[to], "--node", str(to), "--takeover",
                              f"--start={start}", *self._agent_config(agent))
            try:
                taker = self.kids.add(host.spawn_agent(f"agent-{agent}-m{n}", argv[2:]))
            except Exception as exc:  # noqa: BLE001 (a node that cannot start it: the agent stays where it runs)
                self._moved(agent, was)
                why = (str(exc) or type(exc).__name__).splitlines()[-1][:120]
                _say(f"agent {agent} stays on router {was}: its move did not start ({why})")
                continue
            self.leaving[agent], self.current[agent] = self.current[agent], taker
        if moves and not self.plan.quiet:
            _say(f"t = {t:.1f} s: moved {len(moves)} agents between routers", err=False)

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
                 "--progress", "0" if plan.quiet else "2", "--start-timeout", f"{world_start_timeout(len(plan.ids)):g}"]
        if plan.trajectory is not None:
            extra += ["--trajectory", str(plan.trajectory)]
        if plan.end_after_capture is not None:
            extra += ["--end-after-capture", repr(plan.end_after_capture)]
        if self.spec.clock == "lockstep":  # each fault's start is staged on the run's held clock
            holds = sorted({e.at * self.spec.time_scale for e in self.pending if e.action in FAULT_STARTS})
            extra += ["--hold-at", ",".join(f"{h:g}" for h in holds)] if holds else []
        if resume:
            extra.append("--resume")
        elif plan.design is not None:  # judged before the run started: the world need not judge it again
            extra += ["--design", json.dumps(plan.design)]
        extra += self._viewer().to_argv()
        self.world = self.local.spawn_world(self.spec, self.endpoint, *extra, stdout=subprocess.PIPE)
        forward_lines(self.world, self._forward)

    def _forward(self, text: str) -> None:
        """Pass the world's lines through (quiet: only its last)."""
        if not self.plan.quiet or text.startswith(DONE):
            sys.stdout.write(text)
            sys.stdout.flush()

    # --- while it runs --------------------------------------------------------------------------------

    def _supervise(self) -> int:
        """Wait for the world to finish (or, without a world, for the agents / for Ctrl-C)."""
        t0: float | None = None if self.watch is not None else time.monotonic()
        while True:
            if t0 is None and self.world_started.is_set():
                t0 = time.monotonic()  # chaos times count from the start of the world's clock
            if t0 is not None:
                self._stage_due(time.monotonic() - t0)
            run_t = None if t0 is None else (time.monotonic() - t0) * self.spec.time_scale
            if (run_t is not None and self.migration is not None and self.world is not None and self.world.alive()
                    and self.migration.due(run_t)
                    and run_t < self.spec.steps * self.spec.scenario.dt - max(1.0, MOVE_WALL_S * self.spec.time_scale)):
                self._migrate(run_t)  # not near the run's end: a move must be over before it ends
            self._note_crashes()
            if self.world is not None and not self.world.alive() and not self.world_down:
                break
            if self._all_crashed():
                self._agents_verdict("; stopping the run")
                self.kids.stop_all()
                self._finish_recording()
                return 1
            if self.world is None and "agents" in self.plan.roles and not any(
                    c.alive() for c in self.kids.named("agent")):
                return self._agents_verdict()
            dead = self._dead_routers()
            if dead:
                _say(f"the router died ({', '.join(dead)}); stopping the run")
                self.kids.stop_all()
                self._finish_recording()
                return 1
            # lockstep runs its clock as fast as its agents answer: a fault due on it is looked for more often
            time.sleep(0.02 if self.pending and self.spec.clock == "lockstep" else 0.1)
        self._let_go(None if t0 is None else time.monotonic() - t0)
        Children.stop(self.kids.named("agent"), 5.0)  # they end on the world's final tick; this reaps them
        code = self.world.proc.returncode
        self._finish_recording()
        if self.world_crash_for_good:
            return 0  # the run ended where it was asked to (--world-crash T)
        return 0 if code == 0 else (2 if code == 2 else 1)

    def _agents_verdict(self, then: str = "") -> int:
        """The exit status once this machine's agents have all exited: 1, said in the last line, when any
        exited with an error (their laws failed, none could reach the router, an id had no spawn position...)."""
        failed = sorted(self._agent_errors())
        if not failed:
            return 0
        total = len(self.kids.named("agent"))
        _say(f"{'every one' if len(failed) == total else f'{len(failed)} of {total}'} of this machine's agents "
             f"exited with an error (agents {id_ranges(failed)}; their lines above say why){then}")
        return 1

    def _note_crashes(self) -> None:
        for c in self.kids.children:
            code = c.proc.poll()
            if (code not in (None, 0) and c.name.startswith("agent") and c.name not in self.crashed
                    and c.name not in self.expected_exits):
                self.crashed.add(c.name)
                others = any(o.alive() for o in self.kids.named("agent"))
                if code != EXIT_LAW_FAILED:  # a failed law says so in its agent's own line
                    _say(f"{c.name} exited with code {code}{'; the others carry on' if others else ''}")

    def _all_crashed(self) -> bool:
        """Every agent of this machine exited with an error nobody asked for, and none is to restart."""
        agents = self.kids.named("agent")
        return (bool(agents) and "agents" in self.plan.roles and not any(c.alive() for c in agents)
                and not any(e.action == "restart_agents" for e in self.pending)
                and all(c.name in self.crashed for c in agents if c.name not in self.expected_exits)
                and any(c.name in self.crashed for c in agents))

    def _stage_due(self, wall: float) -> None:
        """Stage each event that has fallen due, ``wall`` seconds after the world's clock started. A fault
        starts at its time on the run's clock: the wall time, or, in lockstep (a run as fast as its agents
        answer), the world's last tick; it ends (unpause, restart, resume) as many wall seconds after it
        started as it was asked to last."""
        lockstep = self.spec.clock == "lockstep" and self.watch is not None
        started = False
        for event in list(self.pending):
            key = event.what or event.action.rsplit("_", 1)[1]  # what a fault's start and its end share
            if event.action in FAULT_STARTS:
                due = (self.watch.run_t / self.spec.time_scale if lockstep else wall) >= event.at
                if due:  # (free: its end keeps its own time, so that faults given in turn stay in turn)
                    self.began[key] = wall - event.at if lockstep else 0.0
            else:
                due = key in self.began and wall >= event.at + self.began[key]
            if due:
                self.pending.remove(event)
                self._stage(event, wall)
                started |= event.action in FAULT_STARTS
        # once for the faults due at one held time: a second signal would let the next hold pass at once
        if lockstep and started and self.world is not None and self.world.alive():
            self.world.proc.send_signal(signal.SIGUSR1)  # its clock, held for these, goes on

    def _let_go(self, wall: float | None) -> None:
        """The run is over: a process still paused is let go now, and a fault that never began is said."""
        for event in list(self.pending):
            if event.action == "unpause" and event.what in self.paused:
                self.pending.remove(event)
                self._stage(event, wall or 0.0)
            elif event.action == "unpause" and event.what in self.began:  # its pause found nothing to freeze
                self.pending.remove(event)
        if self.pending:
            _say("the run ended before " + ", ".join(f"{e.action.replace('_', ' ')} {e.what}".strip() + f" at {e.at:g} s"
                                                    for e in self.pending) + ": not staged")

    def _stage(self, event: Event, t: float) -> None:
        """Carry out one scheduled event (world events only where this machine runs the world); each one
        staged goes into the summary's ``staged``, at the wall time since the world's clock started."""
        world = self.world
        if world is not None or event.action in ("kill_agents", "restart_agents", "pause", "unpause"):
            self.staged.append({"at_s": round(t, 3), "action": event.action, **({"what": event.what} if event.what else {}),
                                **({"count": event.count} if event.count else {}),
                                **({"run_s": round(self.watch.run_t, 3)} if self.spec.clock == "lockstep" and self.watch
                                   else {})})
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
        elif event.action == "pause":
            self._pause(event.what, t)
            return
        elif event.action == "unpause":
            self._unpause(event.what, t)
            return
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

    def _pause(self, what: str, t: float) -> None:
        """Freeze the process named ``what`` (its newest, where an agent has moved), as a machine that
        stops scheduling it would."""
        live = [c for c in self.kids.children if (c.name == what or c.name.startswith(f"{what}-m")) and c.alive()]
        if not live:
            self.staged[-1]["not_running"] = True
            _say(f"{what} is not running at {t:.1f} s: nothing to pause")
            return
        live[-1].proc.send_signal(signal.SIGSTOP)
        self.paused[what] = live[-1]
        _say(f"{what} paused at {t:.1f} s")

    def _unpause(self, what: str, t: float) -> None:
        child = self.paused.pop(what, None)
        if child is not None and child.alive():
            child.proc.send_signal(signal.SIGCONT)
            _say(f"{what} resumed at {t:.1f} s")

    # --- end ------------------------------------------------------------------------------------------

    def _dead_routers(self) -> list[str]:
        """The routers of this run that died (a run stops when one does: its agents are cut off)."""
        return [c.name for c in self.kids.named("router") if not c.alive()]

    def _reach_router(self, endpoint: str) -> None:
        """The router of ``--connect`` answers within the connect timeout, or the run stops here with one
        line (exit 2), before anything starts (each child would say so in a line of its own)."""
        host, port = endpoint_host_port(endpoint)
        wait = self.plan.connect_timeout if self.plan.connect_timeout is not None else CONNECT_TIMEOUT
        if not wait_for_port(local_host(host), port, wait):
            raise UsageError(unreachable(endpoint, wait))

    def _finish_recording(self) -> None:
        """Every run ends with a recording and a summary (:func:`zswarm.launch.ending.finish_recording`)."""
        if "world" not in self.plan.roles or self.world is None or self.world.alive():
            return
        finish_recording(self.plan, self.world.proc.returncode, self.started_at, self._routing(), _say)

    def _agent_errors(self) -> dict[int, int]:
        """The agents whose processes exited with an error nobody asked for: id -> exit status."""
        return {int(c.name.split("-")[1]): c.proc.returncode for c in self.kids.named("agent")
                if c.proc.returncode not in (0, None) and c.name not in self.expected_exits}

    def _routing(self) -> dict:
        """What the launcher adds to the summary: the routers and each agent's, the agents that exited
        with an error (their law failed, or not), how the run was secured, the migration."""
        agent_router = {str(i): self.router_of(i) for i in self.plan.ids} if "agents" in self.plan.roles else {}
        exits = self._agent_errors()
        secure = self.plan.secure is not None
        how = {i: "killed (--kill)" for i in self.killed}  # however each crashed: one key lists them all
        how.update({i: "its law failed" if code == EXIT_LAW_FAILED else f"exited with code {code}"
                    for i, code in exits.items()})
        return {"routers": self.endpoints, "agent_router": agent_router, "crashed_agents": sorted(how),
                "crashes": {str(i): how[i] for i in sorted(how)},
                "law_failures": sorted(i for i, code in exits.items() if code == EXIT_LAW_FAILED),
                "security": {"tls": secure, "acl": secure, "ray_auth": self.ray_auth}, "staged": self.staged,
                **self._migration_summary()}

    @property
    def ray_auth(self) -> str | None:
        """How the Ray cluster the run used lets drivers in ("token"; None: no cluster, or an open one)."""
        return None

    def _migration_summary(self) -> dict:
        return {} if self.migration is None else {"migration": self.migration.summary(len(self.plan.ids))}
