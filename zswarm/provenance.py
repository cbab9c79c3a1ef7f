"""Where a result came from: the versions of everything a run used, and the machine it ran on."""

from __future__ import annotations

import os
import platform
import sys
from typing import Any


def versions() -> dict[str, str]:
    """Versions of zswarm, Python and the libraries a run depends on (Rerun only if installed)."""
    from importlib import metadata

    import numpy as np

    from zswarm import __version__

    def dist(name: str) -> str:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return "not installed"

    return {"zswarm": __version__, "python": sys.version.split()[0], "numpy": np.__version__,
            "rerun-sdk": dist("rerun-sdk"), "eclipse-zenoh": dist("eclipse-zenoh"),
            "msgpack": dist("msgpack"), "platform": platform.platform()}


def machine() -> dict[str, Any]:
    """What a benchmark ran on."""
    return {"cpus": os.cpu_count(), "platform": platform.platform(), "processor": platform.machine(),
            "python": platform.python_version()}
