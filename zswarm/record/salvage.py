"""What is left when a world dies without closing its recording: make the file whole again.

Rerun streams a recording to disk as it goes, so a world killed outright leaves a file with all but
its last fraction of a second, but no footer, which ``rerun rrd verify`` rejects. :func:`seal`
rewrites such a file with rerun's own ``rrd merge`` into a complete one and replaces it only after
checking that the copy verifies and holds the same steps. :func:`salvage_summary` recomputes a
run's summary from its recording when its world could not write one.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

from zswarm.files import write_json


def _rerun(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rerun", *args], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "RUST_LOG": "warn"})


def verify(path: Path) -> bool:
    """Does ``rerun rrd verify`` accept the file?"""
    return _rerun("rrd", "verify", str(path)).returncode == 0


def seal(path: Path) -> bool:
    """Give a killed writer's recording its footer. Returns whether the file was rewritten (False:
    it was complete already). The original is kept only if the rewritten copy does not check out."""
    from zswarm.errors import UsageError
    from zswarm.record.replay import load_segment

    path = Path(path)
    if verify(path):
        return False
    tmp = path.with_name(f".{path.name}.sealing")
    done = _rerun("rrd", "merge", "--continue-on-error", "-o", str(tmp), str(path))
    try:
        if done.returncode != 0 or not verify(tmp):
            raise UsageError(f"cannot repair {path}: rerun rrd merge failed ({done.stderr.strip()[-200:]})")
        before, after = load_segment(path), load_segment(tmp)
        if [f.step for f in before.frames] != [f.step for f in after.frames] or before.config != after.config:
            raise UsageError(f"cannot repair {path}: the rewritten copy differs; the file is left as it is")
        os.replace(tmp, path)
        return True
    finally:
        tmp.unlink(missing_ok=True)


def salvage_summary(record: Path, summary_path: Path) -> dict[str, Any]:
    """The summary of a run whose world died: the metrics recomputed from every recorded segment,
    marked ``"salvaged": true`` (no transport figures: those lived in the world)."""
    from zswarm.record.replay import load_run, recompute, segments

    for part in segments(record):
        seal(part)
    run = load_run(record)
    last = run.frames[-1]
    result = {"salvaged": True, "run": run.config.get("run"), "scenario": run.config.get("scenario"),
              "seed": run.config.get("seed"), "n_agents": run.config.get("n_agents"), "steps": last.step,
              "duration": last.t, "world_segments": len(run.segments), **recompute(run)}
    write_json(summary_path, result)
    return result
