"""The stop flag that SIGINT and SIGTERM set (zswarm.stopping): no lock, so a signal that comes while
another's handler runs cannot deadlock it, as a threading.Event once did in a router."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

from zswarm.host.procs import free_port, wait_for_port
from zswarm.stopping import StopSignal


def test_the_flag_waits_until_set_or_timed_out_and_takes_no_lock_to_set():
    stop = StopSignal()
    assert stop.wait(0.05) is False and not stop.is_set()
    stop.set(signal.SIGTERM, None)  # its own handler signature
    stop.set()  # again, "while" the first runs: nothing to wait on
    assert stop.is_set() and stop.wait(0.0) and stop.wait()
    later = StopSignal()
    threading.Timer(0.1, later.set).start()
    assert later.wait(30.0)  # returns once set from another thread, not at the deadline


def test_a_router_stops_on_a_storm_of_signals():
    """Many SIGINTs and SIGTERMs in a row: each handler only sets the flag; the router exits 0. (The
    deadlock itself, a second signal inside the first handler's Event.set, is a race this does not
    bring about on demand: ten such storms against the old router all ended.)"""
    port = free_port()
    router = subprocess.Popen([sys.executable, "-m", "zswarm.net.router", "--listen", f"tcp/127.0.0.1:{port}"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        assert wait_for_port("127.0.0.1", port, 10.0)
        for k in range(500):
            try:
                os.kill(router.pid, signal.SIGINT if k % 2 else signal.SIGTERM)
            except ProcessLookupError:
                break
        _, err = router.communicate(timeout=30)
        assert router.returncode == 0, err
    finally:
        if router.poll() is None:
            router.kill()
            router.wait()
