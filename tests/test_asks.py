"""An ask that nobody reads the answer to stalls nothing: :data:`zswarm.net.bridge.ASK_QOS`, with real
processes and a real router."""
from __future__ import annotations

import os
import signal
import subprocess
import time

from swarm_procs import freeze, processes
from zswarm.host.procs import start_router
from zswarm.net.config import open_session, zenoh_config

ANSWERER = """
import sys, time
from zswarm.net.bridge import Bridge
from zswarm.net.config import open_session, zenoh_config
session = open_session(zenoh_config("client", [sys.argv[1]]), "answerer", retry_for=30.0)
bridge = Bridge(session, None, deliver=lambda item: None, batch=True)
bridge.queryable("asks/q", lambda params: [("asks/q", bytes(60_000))])  # a large answer: the asker's link fills
print("ready", flush=True)
while True:  # its heartbeat, at 20 Hz
    session.put("asks/beat", b"x")
    time.sleep(0.05)
"""

ASKER = """
import sys, time
from zswarm.net.bridge import Bridge
from zswarm.net.config import open_session, zenoh_config
session = open_session(zenoh_config("client", [sys.argv[1]]), "asker", retry_for=30.0)
bridge = Bridge(session, None, deliver=lambda item: None, batch=True)
print("ready", flush=True)
while True:  # asks as an agent asks its cells, without waiting on the answers
    bridge.get_into_inbox("asks/q", "ask", timeout=30.0)
    time.sleep(0.005)
"""


def test_an_asker_that_stops_reading_stalls_nobody_elses_traffic():
    """An asker stops (SIGSTOP) with answers of 60 kB on their way to it: the answering process's
    heartbeat goes on through the router to a listener. Under Zenoh's default for queries (``block``)
    the router held back everything the answering process sent for 5 s (its link to the stopped asker
    then closed): a world that answered a starved agent fell silent so."""
    with processes() as kids:
        endpoint = start_router(kids)
        answerer = kids.spawn("answerer", ["-c", ANSWERER, endpoint], stdout=subprocess.PIPE)
        assert answerer.proc.stdout.readline().strip() == b"ready"
        with open_session(zenoh_config("client", [endpoint]), "listener", retry_for=30.0) as session:
            beats: list[float] = []
            sub = session.declare_subscriber("asks/beat", lambda sample: beats.append(time.monotonic()))
            asker = kids.spawn("asker", ["-c", ASKER, endpoint], stdout=subprocess.PIPE)
            assert asker.proc.stdout.readline().strip() == b"ready"
            time.sleep(1.0)  # answers flowing
            freeze(asker.proc.pid)
            stopped = time.monotonic()
            time.sleep(8.0)  # longer than the 5 s the router held everything back under "block"
            sub.undeclare()
            os.kill(asker.proc.pid, signal.SIGCONT)
        after = [t for t in beats if t > stopped]
        gaps = [b - a for a, b in zip([stopped, *after], after)]
        assert len(after) > 60 and max(gaps) < 1.0, (len(after), round(max(gaps, default=-1.0), 2))
