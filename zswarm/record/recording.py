"""Opening Rerun recordings (``.rrd``) safely: one place that turns a bad path into a usage error."""

from __future__ import annotations

from pathlib import Path

import rerun as rr
import rerun.blueprint as rrb

from zswarm.files import check_writable
from zswarm.record.live import Viewer, sinks

__all__ = ["check_writable", "close_recording", "open_recording"]


def open_recording(path: Path | None, application_id: str, blueprint: rrb.Blueprint,
                   recording_id: str | None = None, viewer: Viewer | None = None) -> rr.RecordingStream:
    """A recording stream that saves to ``path`` (checked first) and/or streams to ``viewer``, with its
    default blueprint."""
    if path is not None:
        check_writable(path, (".rrd",))
    rec = rr.RecordingStream(application_id, recording_id=recording_id)
    if viewer is None or not viewer.wanted:
        rec.save(path, default_blueprint=blueprint)
    else:
        rec.set_sinks(*sinks(path, viewer), default_blueprint=blueprint)
    return rec


def close_recording(rec: rr.RecordingStream, hold: bool = False) -> None:
    """Flush everything and close the file (writes the footer). ``hold``: a process that serves its
    recording (``--serve``) keeps serving it until Ctrl-C, so a late browser still sees the whole run."""
    rec.flush()
    if hold:
        import time

        print("the run is done; still serving it (Ctrl-C to stop)", flush=True)
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            pass
    rec.disconnect()
