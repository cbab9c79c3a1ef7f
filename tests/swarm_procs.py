"""Helpers to run real router/world/agent processes in tests; everything is reaped in ``finally``."""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Iterator

from zswarm.host.local import LocalHost
from zswarm.host.procs import Child, Children, agent_argv
from zswarm.net.runspec import RunSpec, add_run_args, spec_from_args

from conftest import PROCESS_LOGS


class LoggedChildren(Children):
    """Children whose output, where the caller does not take it, goes to a log file of its own in
    ``folder``: a failing test's report shows its end (conftest's ``PROCESS_LOGS``)."""

    def __init__(self, folder: Path) -> None:
        super().__init__()
        self.folder = folder

    def spawn(self, name: str, args, stdout=None, stderr=None, **kw) -> Child:
        if stdout is not None and stderr is not None:
            return super().spawn(name, args, stdout=stdout, stderr=stderr, **kw)
        path = self.folder / f"{len(PROCESS_LOGS):03d}-{name}.log"
        PROCESS_LOGS.append((name, path))
        with open(path, "wb") as log:
            return super().spawn(name, args, stdout=log if stdout is None else stdout,
                                 stderr=log if stderr is None else stderr, **kw)


@contextlib.contextmanager
def processes() -> Iterator[Children]:
    """Children for a test, all stopped and reaped at its end; their logs live until the test's report is made."""
    folder = Path(tempfile.mkdtemp(prefix="zswarm-logs-"))
    kids = LoggedChildren(folder)
    try:
        yield kids
    finally:
        kids.stop_all(grace=3.0)
        _HOSTS.pop(id(kids), None)
        PROCESS_LOGS.append(("", folder))  # (a folder: removed with the test's logs)


def split_spec(run: str, scenario: str, *args: str) -> tuple[RunSpec, list[str]]:
    """The run spec that ``--run RUN --scenario SCENARIO ARGS`` describe, and the other arguments."""
    parser = argparse.ArgumentParser()
    add_run_args(parser)
    known, rest = parser.parse_known_args(["--run", run, "--scenario", scenario, *args])
    return spec_from_args(known), rest


def start_world(kids: Children, endpoint: str, run: str, scenario: str, tmp: Path, *extra: str,
                name: str = "world", judges: bool = False) -> tuple:
    """The world of a run, handed its design verdict as ``zswarm run`` hands it (``judges``: left to judge
    it itself, beside its starting swarm)."""
    summary, record, traj = tmp / f"{run}.json", tmp / f"{run}.rrd", tmp / f"{run}.npz"
    spec, rest = split_spec(run, scenario, *extra)
    if not judges and "--design" not in rest and "--resume" not in rest:
        rest = [*rest, "--design", design_of(spec.scenario.params, spec.scenario.dt, spec.safety)]
    child = host_of(kids).spawn_world(spec, endpoint, *rest, "--summary", str(summary), "--record", str(record),
                                      "--trajectory", str(traj), "--progress", "0", name=name)
    return child, summary, record, traj


@functools.lru_cache(maxsize=32)
def design_of(params, dt: float, safety: str) -> str:
    """A set's design verdict in JSON, judged once per test worker."""
    from zswarm.design.guidelines import verdict

    return json.dumps(verdict(params, dt, safety))


#: The host of each set of children, which starts its processes as ``zswarm run``'s does: its agents
#: forked from one fleet (the agent program imported once, each agent forked from it in milliseconds,
#: still its own process with its own process group and pid).
_HOSTS: dict[int, LocalHost] = {}


def host_of(kids: Children) -> LocalHost:
    return _HOSTS.setdefault(id(kids), LocalHost(kids))


def start_agent(kids: Children, endpoint: str, run: str, scenario: str, agent: int, *extra: str):
    spec, rest = split_spec(run, scenario, *extra)
    return host_of(kids).spawn_agent(f"agent-{agent}", agent_argv(spec, agent, endpoint, *rest)[2:])


def with_reference(summary_path: Path, run: str, scenario: str, *extra: str) -> dict:
    """The world's summary with the reference simulation beside it (as ``zswarm run`` adds it)."""
    from zswarm.launch.reference import add_reference

    load_summary(summary_path)
    return add_reference(summary_path, split_spec(run, scenario, *extra)[0])


def freeze(pid: int, timeout: float = 10.0) -> None:
    """SIGSTOP ``pid`` and return once every thread of it has stopped. The signal stops a process only
    when one of its threads takes it; on a loaded machine its other threads went on for a while after
    ``kill`` returned (a frozen router answered an ask sent just after: tests/test_bridge.py)."""
    os.kill(pid, signal.SIGSTOP)
    deadline = time.monotonic() + timeout
    while True:
        states = []
        for task in Path(f"/proc/{pid}/task").iterdir():
            try:
                states.append((task / "stat").read_text().rsplit(")", 1)[1].split()[0])
            except (OSError, IndexError):
                continue  # a thread that ended
        if states and all(state in "tT" for state in states):
            return
        assert time.monotonic() < deadline, f"process {pid} not stopped after {timeout:g} s: {states}"
        time.sleep(0.005)


def wait_exit(child, timeout: float) -> int:
    try:
        return child.proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"{child.name} did not finish within {timeout} s") from None


def load_summary(path: Path) -> dict:
    deadline = time.monotonic() + 5
    while not path.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    return json.loads(path.read_text())


def interrupt_when_exists(proc: subprocess.Popen, path: Path, timeout: float = 120.0,
                          sig: int = signal.SIGINT) -> bool:
    """Wait for ``path`` to appear, send ``sig`` (SIGINT) and reap the process (killed if it does not
    end). Returns whether the file appeared."""
    try:
        deadline = time.monotonic() + timeout
        while not path.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        appeared = path.exists()
        proc.send_signal(sig)
        proc.wait(timeout=60)
        return appeared
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def interrupt_at_step(proc: subprocess.Popen, endpoint: str, run: str, step: int, sig: int = signal.SIGINT,
                      timeout: float = 120.0) -> None:
    """Wait until the run's world has reached ``step``, send ``sig`` and reap the process (killed if
    it does not end)."""
    try:
        with Watch(endpoint, run) as watch:
            watch.reach_step(step, timeout)
        proc.send_signal(sig)
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def recorded_events(path: Path) -> list[str]:
    """The texts of a recording's event log (``run/events``), in the order they were logged."""
    from rerun.chunk import RrdReader

    out = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if str(chunk.entity_path).lstrip("/") == "run/events":
            rb = chunk.to_record_batch()
            text = [c for c in rb.schema.names if c.endswith("Text") or c.endswith(":text")]
            for col in text:
                out += [str(v[0]) for v in rb.column(col).to_pylist() if v]
    return out


def rerun_verify(path: Path) -> None:
    """``rerun rrd verify`` accepts the file."""
    rerun = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    res = subprocess.run([rerun, "rrd", "verify", str(path)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr


def scalar_series(path: Path) -> dict[str, list[tuple[int, float]]]:
    """Every scalar series of a recording (metrics, thresholds, safety counts): (step, value) rows in
    step order."""
    from rerun.chunk import RrdReader

    out: dict[str, list[tuple[int, float]]] = {}
    for chunk in RrdReader(str(path)).stream().to_chunks():
        rb = chunk.to_record_batch()
        if "Scalars:scalars" in rb.schema.names and "step" in rb.schema.names:
            values = [v[0] for v in rb.column("Scalars:scalars").to_pylist()]
            out.setdefault(str(chunk.entity_path).lstrip("/"), []).extend(zip(rb.column("step").to_pylist(), values))
    return {k: sorted(v) for k, v in out.items()}


def map_agents(path: Path) -> list[tuple[int, int, list[str] | None]]:
    """The map's agent points in a recording, as (step, how many positions, labels or None where that
    row updated only the positions), in step order (2-D or 3-D)."""
    from rerun.chunk import RrdReader

    from zswarm.record.swarm_log import AGENTS

    rows = []
    for chunk in RrdReader(str(path)).stream().to_chunks():
        if str(chunk.entity_path).lstrip("/") != AGENTS:
            continue
        rb = chunk.to_record_batch()
        kind = "Points3D" if "Points3D:positions" in rb.schema.names else "Points2D"
        labels = (rb.column(f"{kind}:labels").to_pylist() if f"{kind}:labels" in rb.schema.names
                  else [None] * rb.num_rows)
        for step, positions, text in zip(rb.column("step").to_pylist(), rb.column(f"{kind}:positions").to_pylist(),
                                         labels):
            rows.append((step, len(positions), text))
    return sorted(rows, key=lambda r: r[0])


def our_processes(marker: str) -> list[int]:
    """Pids of every process whose command line holds ``marker`` (a run id): should be none."""
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if marker in (d / "cmdline").read_bytes().decode(errors="replace"):
                    out.append(int(d.name))
            except OSError:
                pass
    return out


def run_launch(cwd: Path, *args: str, timeout: float = 180.0) -> subprocess.CompletedProcess:
    """``python launch.py ARGS`` to completion (killed on timeout), output captured as text."""
    from conftest import ROOT, run_cli

    return run_cli(str(ROOT / "launch.py"), *args, cwd=cwd, timeout=timeout)


class Watch:
    """A listener on a run's keys (it publishes nothing): the world's step from its prey messages (or
    its ticks, in lockstep) and who holds a liveliness token, so a test can wait for the event it is about."""

    def __init__(self, endpoint: str, run: str) -> None:
        import threading

        import zenoh

        from zswarm.net import messages as msg
        from zswarm.net.config import open_session, zenoh_config
        from zswarm.net.keys import Keys

        keys = Keys(run, 1.0)
        self.step = -1
        self.alive: set[int] = set()
        self.changed = threading.Condition()

        def on_step(sample) -> None:  # the prey (free clock) or a tick (lockstep) names the world's step
            try:
                m = msg.decode(sample.payload.to_bytes())
            except msg.DecodeError:
                return
            with self.changed:
                self.step = max(self.step, m.seq if isinstance(m, msg.Prey) else m.step if isinstance(m, msg.Tick)
                                else self.step)
                self.changed.notify_all()

        def on_alive(sample) -> None:
            who = keys.agent_of(str(sample.key_expr))
            with self.changed:
                if who is not None:
                    (self.alive.discard if sample.kind == zenoh.SampleKind.DELETE else self.alive.add)(who)
                self.changed.notify_all()

        self.session = open_session(zenoh_config("client", [endpoint]), "watch", retry_for=60.0)  # router may be starting
        self.subs = [self.session.declare_subscriber(keys.prey, on_step), self.session.declare_subscriber(keys.tick, on_step),
                     self.session.liveliness().declare_subscriber(keys.all_alive, on_alive, history=True)]

    def until(self, condition, timeout: float, what: str) -> None:
        """Wait until ``condition()`` holds (checked on every change), or fail after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        with self.changed:
            while not condition():
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"timed out after {timeout} s waiting for {what} (step {self.step}, "
                                         f"alive {sorted(self.alive)})")
                self.changed.wait(min(left, 0.5))

    def reach_step(self, step: int, timeout: float = 60.0) -> None:
        self.until(lambda: self.step >= step, timeout, f"world step {step}")

    def close(self) -> None:
        for s in self.subs:
            s.undeclare()
        self.session.close()

    def __enter__(self) -> "Watch":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def cross_router_share(heard: dict[int, dict[int, int]], node_of: dict[int, int]) -> float | None:
    """The share of the poses agents took in that came from an agent on another node (another router),
    from who heard whom: ``heard[receiver][sender]`` counts poses. None when nothing was heard. The
    oracle a run's measured ``cross_router_share`` (each pose names its sender's router) is held to."""
    total = crossed = 0
    for receiver, senders in heard.items():
        for sender, count in senders.items():
            if receiver in node_of and sender in node_of:
                total += count
                crossed += count if node_of[receiver] != node_of[sender] else 0
    return crossed / total if total else None


def agent_state(endpoint: str, run: str, agent_id: int, x: float):
    """One agent process's whole state (:class:`agents.main.Process`, as ``python -m agents`` builds it)
    at (x, 0.5) of bench-field, in this process, over the router at ``endpoint``."""
    from agents.main import Process, build_parser
    from zswarm.net.runspec import spec_from_args

    args = build_parser().parse_args(["--id", str(agent_id), "--start", f"{x},0.5", "--run", run,
                                      "--scenario", "bench-field", "--set", "n_agents=2", "--connect", endpoint])
    return Process(spec_from_args(args), args, loop=None)


def stand_in_world(router, keys):
    """A queryable on ``router`` that answers the obstacle query as a world without obstacles does."""
    from zswarm.net import messages as msg

    no_obstacles = msg.encode(msg.Obstacles((), (), 2))
    return router.declare_queryable(keys.obstacles, lambda q: q.reply(keys.obstacles, no_obstacles))
