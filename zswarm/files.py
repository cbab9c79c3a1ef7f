"""Files a run writes: checked before anything starts, and written whole or not at all."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from zswarm.errors import UsageError


def check_writable(path: Path, suffixes: tuple[str, ...] | None = None) -> Path:
    """Fail early, with one line, if ``path`` cannot be written, or does not end in one of ``suffixes``.

    A path that does not exist yet is probed by creating it and removing it again, so a directory that
    only looks writable (``/proc``, a read-only mount) fails here and not after the work is done.
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    wanted = " or ".join(suffixes) if suffixes else None
    if path.is_dir():
        raise UsageError(f"cannot write {path}: it is a directory; give a file name"
                         + (f" ending in {wanted}" if wanted else ""))
    if suffixes and path.suffix.lower() not in suffixes:
        raise UsageError(f"cannot write {path}: give a file name ending in {wanted}")
    if not parent.is_dir():
        raise UsageError(f"cannot write {path}: directory {parent} does not exist")
    if path.exists():
        if not os.access(path, os.W_OK):
            raise UsageError(f"cannot write {path}: the file is not writable")
        return path
    try:
        os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
        os.unlink(path)
    except OSError as exc:
        raise UsageError(f"cannot write {path}: cannot create a file in {parent} ({exc.strerror})") from None
    return path


def out_dir(folder: Path, flag: str = "--out") -> Path:
    """The output folder ``folder`` (``flag``'s), made if missing; one line (UsageError) when it is a
    file or cannot be made or written."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{flag} {folder} is a file; give a directory")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot create {flag} {folder}: {exc.strerror or exc}") from None
    return folder


def check_run_files(record: Path | None, summary: Path | None, trajectory: Path | None) -> None:
    """The files a run writes (``--record``, ``--summary``, ``--trajectory``), each with its extension."""
    for path, suffix in ((record, ".rrd"), (summary, ".json"), (trajectory, ".npz")):
        if path is not None:
            check_writable(path, (suffix,))


def read_toml(path: Path | str, what: str) -> dict[str, Any]:
    """A TOML file as a dict; a missing, unreadable or malformed file is one line naming ``what`` it is."""
    import tomllib

    try:
        return tomllib.loads(Path(path).read_text())
    except FileNotFoundError:
        raise UsageError(f"{what} {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UsageError(f"cannot read {what} {path}: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{what} {path} is not valid TOML: {exc}") from None


def write_json(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` whole or not at all (a reader never sees half a file), through a temporary file of
    this writer's own: two processes writing the same file at once never mix their contents."""
    import tempfile

    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", prefix=f".{path.name}-", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as out:
            out.write(json.dumps(data, indent=2, sort_keys=True))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
