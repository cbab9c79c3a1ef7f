"""One distributed run as a child ``zswarm run``, finished only when its summary is in place.

The child writes its summary to ``NAME.part.json`` and only a run that exits 0 has it moved to
``NAME.json``: a sweep cell or a confirmation run whose summary exists is finished, and one that was
interrupted is run again (``zswarm sweep`` and ``zswarm tune --confirm`` both resume this way).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from zswarm.net.runspec import RunSpec


def run_once(spec: RunSpec, record: Path, summary: Path, what: str) -> None:
    """Run ``spec`` to its end; raise RuntimeError (naming ``what``) with the child's last words if it fails."""
    part = summary.with_name(summary.name.removesuffix(".json") + ".part.json")
    cmd = [sys.executable, "-m", "zswarm", "run", *spec.to_argv(), "--record", str(record),
           "--summary", str(part), "--quiet"]
    res = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"{what}: zswarm run exited {res.returncode}: {res.stderr.strip()[-300:]}")
    os.replace(part, summary)  # finished only now
