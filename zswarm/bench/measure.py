"""What a process costs, read from ``/proc`` (Linux): CPU time, resident and proportional memory.

PSS (proportional set size) counts a page shared by k processes as 1/k to each, so N agents that
share the interpreter's and the libraries' pages are not charged N times for them; RSS is beside it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

_TICKS = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU seconds the process has used so far (None: it is gone)."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = text[text.rindex(")") + 2:].split()  # after "pid (comm) "; utime, stime are fields 14, 15
    return (int(fields[11]) + int(fields[12])) / _TICKS


def _kb(path: str, label: str) -> float | None:
    try:
        for line in Path(path).read_text().splitlines():
            if line.startswith(label):
                return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


def pss_mb(pid: int) -> float | None:
    return _kb(f"/proc/{pid}/smaps_rollup", "Pss:")


def rss_mb(pid: int) -> float | None:
    return _kb(f"/proc/{pid}/status", "VmRSS:")


@dataclass
class CpuWindow:
    """CPU used by each of a set of processes between :meth:`start` and :meth:`stop`."""

    pids: dict[str, int]
    started: dict[str, float] | None = None
    used: dict[str, float] | None = None
    seconds: float = 0.0

    def start(self, now: float) -> None:
        self.started = {n: c for n, c in ((n, cpu_seconds(p)) for n, p in self.pids.items()) if c is not None}
        self.seconds = -now

    def stop(self, now: float) -> None:
        assert self.started is not None, "start() first"
        ends = {n: cpu_seconds(p) for n, p in self.pids.items()}
        self.used = {n: ends[n] - c for n, c in self.started.items() if ends.get(n) is not None}
        self.seconds += now

    def share(self, names: Iterable[str]) -> list[float]:
        """Each named process's CPU over the window, as a share of one core."""
        assert self.used is not None and self.seconds > 0, "stop() first"
        return [self.used[n] / self.seconds for n in names if n in self.used]
