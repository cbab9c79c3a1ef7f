"""Helpers to run real router/world/agent processes in tests; everything is reaped in ``finally``."""

from __future__ import annotations

import contextlib
import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Iterator

from zswarm.procs import Children


@contextlib.contextmanager
def processes() -> Iterator[Children]:
    kids = Children()
    try:
        yield kids
    finally:
        kids.stop_all(grace=3.0)


def run_args(run: str, scenario: str, *extra: str) -> list[str]:
    return ["--run", run, "--scenario", scenario, *extra]


def start_world(kids: Children, endpoint: str, run: str, scenario: str, tmp: Path, *extra: str,
                name: str = "world") -> tuple:
    summary, record, traj = tmp / f"{run}.json", tmp / f"{run}.rrd", tmp / f"{run}.npz"
    child = kids.spawn(name, ["-m", "world", *run_args(run, scenario, *extra), "--connect", endpoint,
                              "--summary", str(summary), "--record", str(record), "--trajectory", str(traj),
                              "--progress", "0"], stdout=subprocess.DEVNULL)
    return child, summary, record, traj


def start_agent(kids: Children, endpoint: str, run: str, scenario: str, agent: int, *extra: str):
    return kids.spawn(f"agent-{agent}", ["-m", "agents", "--id", str(agent),
                                         *run_args(run, scenario, *extra), "--connect", endpoint],
                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


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


def interrupt_when_exists(proc: subprocess.Popen, path: Path, settle: float = 0.0, timeout: float = 120.0,
                          sig: int = signal.SIGINT) -> bool:
    """Wait for ``path`` to appear, wait ``settle`` more seconds, send ``sig`` (SIGINT) and reap the
    process (killed if it does not end). Returns whether the file appeared."""
    try:
        deadline = time.monotonic() + timeout
        while not path.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        appeared = path.exists()
        time.sleep(settle)
        proc.send_signal(sig)
        proc.wait(timeout=60)
        return appeared
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def rerun_verify(path: Path) -> None:
    """``rerun rrd verify`` accepts the file."""
    rerun = shutil.which("rerun") or str(Path(sys.executable).parent / "rerun")
    res = subprocess.run([rerun, "rrd", "verify", str(path)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr


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
    from zswarm.procs import ROOT

    return subprocess.run([sys.executable, str(ROOT / "launch.py"), *args], cwd=cwd, capture_output=True,
                          text=True, timeout=timeout)
