"""The runs this machine's user is running, by name: where ``zswarm monitor --run RUN`` finds a local
run's router without ``--connect`` (its port is a free one, chosen at start).

``zswarm run`` writes one small file per run, ``RUNS_DIR/RUN``, holding its first router's endpoint and
its own pid (and, for a run over TLS, the Zenoh config of the world's identity, which may watch it),
into a folder only this user can read (``$XDG_RUNTIME_DIR/zswarm-runs``, else ``/tmp/zswarm-runs-UID``),
and removes it when the run ends. A launcher killed outright cannot remove it: an entry whose launcher
is gone is no run, and is removed when it is looked up.
"""

from __future__ import annotations

import os
from pathlib import Path

from zswarm.net.keys import check_run_id


def runs_dir() -> Path:
    base = os.environ.get("XDG_RUNTIME_DIR")
    return Path(base) / "zswarm-runs" if base else Path(f"/tmp/zswarm-runs-{os.getuid()}")


def announce(run: str, endpoint: str, config: Path | None = None) -> Path | None:
    """Say that ``run`` is running here, reached at ``endpoint`` (over TLS with the Zenoh ``config`` of an
    identity that may watch it, for a ``--secure`` run); the file, or None where it cannot be written
    (the run goes on: only the lookup is lost)."""
    folder = runs_dir()
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        if folder.stat().st_uid != os.getuid():  # someone else's folder: not one to trust or write to
            return None
        path = folder / run
        path.write_text(f"{endpoint} {os.getpid()}\n" + ("" if config is None else f"{Path(config).resolve()}\n"))
        return path
    except OSError:
        return None


def forget(path: Path | None) -> None:
    if path is not None:
        path.unlink(missing_ok=True)


def endpoint_of(run: str) -> tuple[str, Path | None] | None:
    """The endpoint of the local run ``run``, and the Zenoh config to watch it with (None: an open run),
    if this user is running it here."""
    check_run_id(run)
    folder = runs_dir()
    path = folder / run
    try:
        if folder.stat().st_uid != os.getuid():
            return None
        first, _, config = path.read_text().partition("\n")
        endpoint, pid = first.split()
        os.kill(int(pid), 0)  # its launcher is alive
    except ProcessLookupError:
        forget(path)  # a launcher killed outright left it
        return None
    except (OSError, ValueError):
        return None
    return endpoint, Path(config.strip()) if config.strip() else None
