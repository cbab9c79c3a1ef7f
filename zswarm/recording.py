"""Opening Rerun recordings (``.rrd``) safely: one place that turns a bad path into a usage error."""

from __future__ import annotations

import os
from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from zswarm.cli_util import UsageError


def check_writable(path: Path) -> Path:
    """Fail early, with one line, if ``path`` cannot be written."""
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise UsageError(f"cannot write {path}: it is a directory; give a file name ending in .rrd")
    if not parent.is_dir():
        raise UsageError(f"cannot write {path}: directory {parent} does not exist")
    if not os.access(parent, os.W_OK):
        raise UsageError(f"cannot write {path}: directory {parent} is not writable")
    return path


def open_recording(path: Path, application_id: str, blueprint: rrb.Blueprint,
                   recording_id: str | None = None) -> rr.RecordingStream:
    """A recording stream that saves to ``path`` (checked first), with its default blueprint."""
    check_writable(path)
    rec = rr.RecordingStream(application_id, recording_id=recording_id)
    rec.save(path, default_blueprint=blueprint)
    return rec


def close_recording(rec: rr.RecordingStream) -> None:
    """Flush everything and close the file (writes the footer)."""
    rec.flush()
    rec.disconnect()
