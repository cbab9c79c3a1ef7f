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
from collections import deque

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


#: The ports :func:`free_port` handed out last in this process, not handed out again: the routers of
#: one run (``--routers K``: K ports picked before any router binds) never get the same one.
_GIVEN: deque[int] = deque(maxlen=256)


def free_port(host: str = LOOPBACK) -> int:
    """A TCP port nothing listens on at ``host`` now, and not one of this process's last ones."""
    span = port_range()
    for _ in range(200):
        port = 0 if span is None else random.randint(*span)
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind((host, port))
            except OSError:
                if span is None:  # the kernel found none: the address is not this machine's
                    raise
                continue
            port = s.getsockname()[1]
        if port not in _GIVEN:
            _GIVEN.append(port)
            return port
    raise UsageError("no free port after 200 tries" + ("" if span is None else
                     f" in ZSWARM_PORTS={span[0]}-{span[1]}: widen the range"))


def local_host(host: str) -> str:
    """Where to check a listening port: a wildcard address is reached on loopback."""
    return LOOPBACK if host in ("0.0.0.0", "::") else host


def port_in_use(host: str, port: int, timeout: float = 0.2) -> bool:
    """Something accepts a TCP connection at ``host``:``port`` within ``timeout`` seconds."""
    try:
        with socket.create_connection((host, port), timeout=timeout):
            return True
    except OSError:
        return False
