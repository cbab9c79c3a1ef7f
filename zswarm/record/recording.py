"""Opening Rerun recordings (``.rrd``) safely: one place that turns a bad path into a usage error."""

from __future__ import annotations

from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from zswarm.files import check_writable

__all__ = ["check_writable", "close_recording", "open_recording"]


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
