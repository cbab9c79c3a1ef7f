"""What every zswarm process does at its start, before it imports numpy: die with its parent, and
keep to one BLAS thread. The base of the process programs (``agents``, ``world``) and of the host
that starts them (:mod:`zswarm.host.procs`)."""

from __future__ import annotations

import ctypes
import signal
from typing import MutableMapping

_PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """SIGTERM this process when its parent dies (run in a child, between fork and exec or the program)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)
    except OSError:
        pass


BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_blas_thread(env: MutableMapping[str, str]) -> None:
    """One BLAS thread unless the user set otherwise; call it before numpy is imported. A swarm
    process does its linear algebra on small arrays, and an idle BLAS pool of one thread per core
    spins between calls: on a 16-core machine the world burned 2.2 cores at N = 100 and 9.5 at
    N = 400 that way (docs/benchmarks.md), cores its agents needed."""
    for name in BLAS_THREADS:
        env.setdefault(name, "1")
