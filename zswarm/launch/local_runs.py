"""The runs this machine's user is running, by name: where ``zswarm monitor --run RUN`` finds a local
run's router without ``--connect`` (its port is a free one, chosen at start).

``zswarm run`` writes one small file per run, ``RUNS_DIR/RUN``, holding its first router's endpoint and
its own pid, into a folder only this user can read (``$XDG_RUNTIME_DIR/zswarm-runs``, else
``/tmp/zswarm-runs-UID``), and removes it when the run ends. A launcher killed outright cannot remove
it: an entry whose launcher is gone is no run, and is removed when it is looked up.
"""

from __future__ import annotations

import os
from pathlib import Path

from zswarm.net.keys import check_run_id


def runs_dir() -> Path:
    base = os.environ.get("XDG_RUNTIME_DIR")
    return Path(base) / "zswarm-runs" if base else Path(f"/tmp/zswarm-runs-{os.getuid()}")


def announce(run: str, endpoint: str) -> Path | None:
    """Say that ``run`` is running here, reached at ``endpoint``; the file, or None where it cannot be
    written (the run goes on: only the lookup is lost)."""
    folder = runs_dir()
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        if folder.stat().st_uid != os.getuid():  # someone else's folder: not one to trust or write to
            return None
        path = folder / run
        path.write_text(f"{endpoint} {os.getpid()}\n")
        return path
    except OSError:
        return None


def forget(path: Path | None) -> None:
    if path is not None:
        path.unlink(missing_ok=True)


def endpoint_of(run: str) -> str | None:
    """The endpoint of the local run ``run``, if this user is running it here."""
    check_run_id(run)
    folder = runs_dir()
    path = folder / run
    try:
        if folder.stat().st_uid != os.getuid():
            return None
        endpoint, pid = path.read_text().split()
        os.kill(int(pid), 0)  # its launcher is alive
    except ProcessLookupError:
        forget(path)  # a launcher killed outright left it
        return None
    except (OSError, ValueError):
        return None
    return endpoint
