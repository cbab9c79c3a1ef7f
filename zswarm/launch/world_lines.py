"""What a world process prints, read by whoever started it: one reader, one rule for "started".

The world prints ``world: started ...`` when its clock starts (chaos times, benchmark windows and a
soak's samples all count from there) and ``world: done ...`` at the end.
"""

from __future__ import annotations

import threading
from typing import Callable

from zswarm.net.procs import Child

STARTED = "world: started"
DONE = "world: done"


def follow_world(world: Child, on_line: Callable[[str], None] | None = None) -> threading.Event:
    """Read ``world``'s standard output (a pipe) on a thread to its end, passing each line to
    ``on_line``; the event returned is set when the world's clock starts."""
    started = threading.Event()

    def read() -> None:
        for line in world.proc.stdout:
            text = line.decode(errors="replace") if isinstance(line, bytes) else line
            if text.startswith(STARTED):
                started.set()
            if on_line is not None:
                on_line(text)
    threading.Thread(target=read, daemon=True, name=f"{world.name}-lines").start()
    return started
