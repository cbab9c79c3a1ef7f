"""What a world process prints, passed on by the launcher that started it.

The world prints ``world: started ...`` when its clock starts and ``world: done ...`` at the end, for
the user; whoever needs the start itself hears it on Zenoh (:mod:`zswarm.launch.world_watch`).
"""

from __future__ import annotations

import threading
from typing import Callable

from zswarm.host.procs import Child

DONE = "world: done"


def forward_lines(world: Child, on_line: Callable[[str], None]) -> None:
    """Read ``world``'s standard output (a pipe) on a thread to its end, passing each line to ``on_line``."""
    def read() -> None:
        for line in world.proc.stdout:
            on_line(line.decode(errors="replace") if isinstance(line, bytes) else line)
    threading.Thread(target=read, daemon=True, name=f"{world.name}-lines").start()
