"""Results kept on disk between commands, keyed by their inputs and by the code that computed them
(docs/design.md, "The swarm check's cache")."""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path
from typing import Any

from zswarm.files import write_json

#: ``ZSWARM_CACHE``: the folder (default ``$XDG_CACHE_HOME/zswarm``, else ``~/.cache/zswarm``), or ``off``.
ENV = "ZSWARM_CACHE"
#: At most this many results are kept; beyond it the older half goes.
MAX_ENTRIES = 4096


def cache_dir() -> Path | None:
    """Where results are kept, or None when ``ZSWARM_CACHE=off``."""
    where = os.environ.get(ENV, "")
    if where.lower() == "off":
        return None
    if where:
        return Path(where)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "zswarm"


@lru_cache(maxsize=1)
def code_digest() -> str:
    """A digest of every source file of the installed zswarm and of numpy's version: a result computed
    by other code is never taken for this code's."""
    import numpy

    root = Path(__file__).resolve().parent
    digest = hashlib.sha256(numpy.__version__.encode())
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def kept(kind: str, key: str, compute: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """``compute()``'s result for ``key``: read from the cache when this code computed it before, else
    computed and kept. A cache that cannot be read or written is no cache, never an error."""
    folder = cache_dir()
    if folder is None:
        return compute()
    name = hashlib.sha256(f"{kind}\0{key}\0{code_digest()}".encode()).hexdigest()[:32]
    path = folder / f"{kind}-{name}.json"
    try:
        found = json.loads(path.read_text())
        if isinstance(found, dict) and found.get("key") == key:
            return found["value"]
    except (OSError, ValueError, KeyError):
        pass
    value = compute()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        write_json(path, {"key": key, "value": value})  # whole, whoever writes the same result at once
        _prune(folder)
    except OSError:
        pass
    return value


def _prune(folder: Path) -> None:
    """Keep the newer half once there are more than :data:`MAX_ENTRIES` results."""
    entries = list(folder.glob("*.json"))
    if len(entries) <= MAX_ENTRIES:
        return
    entries.sort(key=_mtime)
    for path in entries[: len(entries) - MAX_ENTRIES // 2]:
        path.unlink(missing_ok=True)


def _mtime(path: Path) -> float:
    try:
        return path.stat().st_mtime
    except OSError:  # gone meanwhile: another command pruned it
        return 0.0
