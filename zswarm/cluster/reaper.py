"""``python -m zswarm.cluster.reaper PID DIR``: the guard of a Ray cluster started on this machine
(``--cluster local[:K]``). While process PID (the driver) runs, it notes Ray's processes below it; when
the driver is gone, by any death, SIGKILL included, it kills those and every process whose environment holds ``ZSWARM_RAY_RUN=DIR`` (or this run's ``RAY_TMPDIR`` or
``HOME``: the nodes' raylets, their
dashboard and runtime-env agents, workers: Ray leaves some of them running when its driver is
killed) and removes DIR. It exits at once, doing nothing, when DIR is removed first (a driver that
ended normally shut its cluster down itself)."""

from __future__ import annotations

import os
import shutil
import signal
import sys
import time
from pathlib import Path

#: Every process of a cluster started here inherits ``TAG=<its run folder>`` (zswarm.cluster.ray_env).
TAG = "ZSWARM_RAY_RUN"


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    fields = _fields(pid)
    return fields is not None and fields[0] != "Z"  # a zombie is gone too


def _fields(pid: int) -> list[str] | None:
    """The fields of ``/proc/PID/stat`` after the command name (state first), None if it is gone."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None


def tagged(tags: set[bytes]) -> list[int]:
    """Processes whose environment holds one of ``tags``."""
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and int(entry.name) != os.getpid():
            try:
                if tags & set((entry / "environ").read_bytes().split(b"\0")):
                    out.append(int(entry.name))
            except OSError:
                continue
    return out


def reap(directory: Path) -> int:
    """Kill every process of the cluster in ``directory``, until none is left (a few rounds: a raylet may
    start a worker meanwhile); returns how many were killed."""
    # Ray's processes set their titles over their own memory, and the start of the environment with it:
    # whichever of the three survives is enough
    tags = {f"{TAG}={directory}".encode(), f"RAY_TMPDIR={directory / 'ray'}".encode(),
            f"HOME={directory / 'home'}".encode()}
    killed = 0
    for _ in range(20):
        pids = tagged(tags)
        if not pids:
            break
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
                killed += 1
            except ProcessLookupError:
                pass
        time.sleep(0.1)
    shutil.rmtree(directory, ignore_errors=True)
    return killed


def _stat(pid: int) -> tuple[int, int] | None:
    """(parent pid, start time) of ``pid``, None if it is gone."""
    fields = _fields(pid)
    try:
        return None if fields is None else (int(fields[1]), int(fields[19]))
    except (IndexError, ValueError):
        return None


def ray_descendants(root: int) -> dict[int, int]:
    """Ray's processes below ``root`` (pid -> start time): the cluster's binaries and Python processes
    (their command line names Ray's package, or their title begins ``ray::``)."""
    parent: dict[int, int] = {}
    start: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            st = _stat(int(entry.name))
            if st is not None:
                parent[int(entry.name)], start[int(entry.name)] = st
    below, frontier = set(), {root}
    while frontier:
        frontier = {p for p, pp in parent.items() if pp in frontier and p not in below}
        below |= frontier
    out = {}
    for pid in below:
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if cmd.startswith(b"ray::") or b"/ray/" in cmd:
            out[pid] = start[pid]
    return out


def kill_seen(seen: dict[int, int]) -> None:
    """SIGKILL each process of ``seen`` still running (the same process: its start time matches)."""
    for pid, started in seen.items():
        st = _stat(pid)
        if st is not None and st[1] == started:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2 or not argv[0].isdigit():
        print("usage: python -m zswarm.cluster.reaper PID DIR", file=sys.stderr)
        return 2
    pid, directory = int(argv[0]), Path(argv[1])
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # a terminal's Ctrl-C is the driver's to handle
    seen: dict[int, int] = {}  # Ray's processes under the driver: once orphaned, nothing else finds them all
    while alive(pid):
        if not directory.exists():
            return 0
        seen.update(ray_descendants(pid))
        time.sleep(0.5)
    kill_seen(seen)
    reap(directory)
    return 0


if __name__ == "__main__":
    sys.exit(main())
