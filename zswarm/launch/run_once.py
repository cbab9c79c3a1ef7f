"""One distributed run as a child ``zswarm run``, finished only when its summary is in place.

The child writes its summary to ``NAME.part.json`` and only a run that exits 0 has it moved to
``NAME.json``: a sweep cell or a confirmation run whose summary exists is finished, and one that was
interrupted is run again (``zswarm sweep`` and ``zswarm tune --confirm`` both resume this way).
An interrupted caller stops the child as a terminal's Ctrl-C would (SIGINT: its agents, then its world,
which flushes its recording) before it goes on, so no world of an abandoned run is still writing the
cell's ``run.rrd`` when a resumed sweep runs that cell again, and the rerun overwrites (``--force``) the
files the unfinished run left.
"""

from __future__ import annotations

import os
import signal
import subprocess
from pathlib import Path
from typing import Sequence

from zswarm.host.procs import Children
from zswarm.net.runspec import RunSpec

STOP_GRACE_S = 30.0


def run_once(spec: RunSpec, record: Path, summary: Path, what: str, extra: Sequence[str] = ()) -> None:
    """Run ``spec`` to its end (``extra``: more ``zswarm run`` options); raise RuntimeError (naming
    ``what``) with the child's last words if it fails."""
    part = summary.with_name(summary.name.removesuffix(".json") + ".part.json")
    args = ["-m", "zswarm", "run", *spec.to_argv(), *extra, "--record", str(record), "--summary", str(part),
            "--quiet", "--force"]  # an unfinished run of this cell left its files: they are redone
    child = Children().spawn("run", args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        _, err = child.proc.communicate()
    finally:  # interrupted: the run ends its world and agents before the caller goes on
        Children.stop([child], STOP_GRACE_S, sig=signal.SIGINT)
    if child.proc.returncode != 0:
        last = err.decode(errors="replace").strip()[-300:]
        raise RuntimeError(f"{what}: zswarm run exited {child.proc.returncode}: {last}")
    os.replace(part, summary)  # finished only now
