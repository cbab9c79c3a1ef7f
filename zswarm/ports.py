"""Free TCP ports for the routers and viewers a run starts on this machine.

By default the kernel picks one (bind to port 0). With ``ZSWARM_PORTS=LO-HI`` set, a port is drawn from
that range instead: processes that pick ports at the same time (the test suite's parallel workers,
each given its own range) then never pick the same one between the moment one is found free and the
moment its router binds it.
"""

from __future__ import annotations

import os
import random
import socket

from zswarm.errors import UsageError


def port_range() -> tuple[int, int] | None:
    """``ZSWARM_PORTS`` as (lo, hi), or None when unset."""
    text = os.environ.get("ZSWARM_PORTS", "").strip()
    if not text:
        return None
    try:
        lo, hi = (int(v) for v in text.split("-"))
    except ValueError:
        raise UsageError(f"ZSWARM_PORTS must be LO-HI, e.g. 20000-24999 (got {text!r})") from None
    if not 1024 <= lo <= hi <= 65535:
        raise UsageError(f"ZSWARM_PORTS must be within 1024-65535 with LO <= HI (got {text!r})")
    return lo, hi


#: The one address a process on this machine binds when nothing says otherwise (loopback: nothing
#: outside the machine reaches it). A run over machines binds the address its user gives.
LOOPBACK = "127.0.0.1"


def free_port(host: str = LOOPBACK) -> int:
    """A TCP port nothing listens on at ``host`` now."""
    span = port_range()
    if span is None:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind((host, 0))
            return s.getsockname()[1]
    for _ in range(200):
        port = random.randint(*span)
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
            return port
    raise UsageError(f"no free port in ZSWARM_PORTS={span[0]}-{span[1]} after 200 tries: widen the range")
