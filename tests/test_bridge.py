"""The bridge's ring-channel inbox, over real Zenoh sessions: what a free-running agent takes in."""

from __future__ import annotations

import os
import time

import zenoh

from conftest import free_port
from zswarm.bench.measure import rss_mb
from zswarm.net.bridge import Bridge
from zswarm.net.config import zenoh_config
from zswarm.net.rings import CELL_CAPACITY, WIDE_CAPACITY


def wait_until(check, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


def test_ring_inbox_keeps_a_senders_last_pose_before_its_departure_and_stamps_only_stamped_arrivals():
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    with zenoh.open(zenoh_config("peer", listen=[endpoint])) as sender, \
            zenoh.open(zenoh_config("peer", connect=[endpoint])) as receiver:
        got: list[tuple] = []
        bridge = Bridge(receiver, None, deliver=got.append, batch=True, channels=True)
        declared = [bridge.subscribe_liveliness("t/alive/*", "alive"),  # subscribed first, taken out last
                    bridge.subscribe("t/pose/*", "pose"),
                    bridge.subscribe("t/probe", "probe", stamped=True)]
        token = sender.liveliness().declare_token("t/alive/1")
        wait_until(lambda: bridge.drain() or any(g[0] == "alive" for g in got), 10.0, "the token")
        got.clear()

        sender.put("t/pose/1", b"last words")
        token.undeclare()  # the sender departs right after its last pose
        sender.put("t/probe", b"marker")  # published after both: once it is in, so are they
        wait_until(lambda: bridge.pending > 0, 10.0, "the stamped marker")
        seen = time.time()
        time.sleep(0.05)
        taken_at = time.time()
        assert bridge.drain() == 3
        assert [(tag, deleted) for tag, _, _, deleted, _ in got] == [("probe", False), ("pose", False), ("alive", True)]
        stamps = {tag: received for tag, _, _, _, received in got}
        assert stamps["probe"] <= seen  # the time it arrived
        assert stamps["pose"] >= taken_at and stamps["alive"] >= taken_at  # the time it was taken out

        pose_sub = declared[1]
        sender.put("t/pose/2", b"in flight")
        sender.put("t/probe", b"marker")
        got.clear()
        wait_until(lambda: bridge.pending > 0, 10.0, "the second marker")
        bridge.unsubscribe(pose_sub)  # what waited in its channel is still delivered
        assert ("pose", "t/pose/2") in [(tag, key) for tag, key, *_ in got]
        assert all(sub is not pose_sub for _, sub in bridge.channels)
        bridge.close()
        for d in (declared[0], declared[2]):
            d.undeclare()


def ring_growth_mb(capacity: int) -> float:
    """How much this process grew while 20,000 samples passed one ring channel of ``capacity`` (drained
    as an agent drains it), after a warm-up round. Run in a fresh interpreter per capacity: the heap
    of a process that already freed a wide channel would lend its pages to the next one."""
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    with zenoh.open(zenoh_config("peer", listen=[endpoint])) as sender, \
            zenoh.open(zenoh_config("peer", connect=[endpoint])) as receiver:
        grew = 0.0
        for name, size in (("warm-up", CELL_CAPACITY), ("measured", capacity)):
            got, ended = [0], []

            def count(item: tuple) -> None:
                got[0] += 1
                if item[2] == b"end":
                    ended.append(True)
            bridge = Bridge(receiver, None, deliver=count, batch=True, channels=True, capacity=size)
            key = f"t/ring/{name}"
            sub = bridge.subscribe(key, "pose")
            publisher = sender.declare_publisher(key)
            wait_until(lambda: (publisher.put(b"hello"), bridge.drain())[1] > 0, 10.0, "the subscription")
            before, base = rss_mb(os.getpid()), got[0]
            for i in range(1, 20_001):
                publisher.put(b"p" * 76)
                if i % 200 == 0:  # taken in before more are sent: what Zenoh itself queues for a receiver
                    # that a loaded machine starves (it grew more than the ring did) is not what this measures
                    wait_until(lambda: (bridge.drain(), got[0] - base >= i)[1], 30.0, "the samples sent")
            # the last sample sent is delivered: every sample that passed the channel has
            wait_until(lambda: (ended or publisher.put(b"end"), bridge.drain())[0] and bridge.drain() == 0, 30.0,
                       "the last sample")
            grew = rss_mb(os.getpid()) - before
            bridge.unsubscribe(sub)
            publisher.undeclare()
        return grew


def test_a_ring_channels_memory_grows_to_its_capacity_so_an_agents_channels_are_small():
    """Why an agent's channels hold CELL_CAPACITY samples: a ring channel's memory grows with the
    samples that passed, drained or not, up to its capacity (16384 slots: about 4 MB a subscription;
    a free agent listening to a dozen cells grew by 1.3 MB a minute in the soak)."""
    import subprocess
    import sys

    from conftest import ROOT

    def measure(capacity: int) -> float:
        out = subprocess.run([sys.executable, "-c", f"import test_bridge; print(test_bridge.ring_growth_mb({capacity}))"],
                             capture_output=True, text=True, timeout=120, cwd=ROOT / "tests",
                             env={**os.environ, "PYTHONPATH": f"{ROOT / 'tests'}:{ROOT}"})
        assert out.returncode == 0, out.stderr[-2000:]
        return float(out.stdout.split()[-1])

    # the smaller of two measurements: what else grows meanwhile (Zenoh's own queues, when a loaded
    # machine starves the receiver) only ever adds to one
    grew = {name: min(measure(capacity), measure(capacity))
            for name, capacity in (("cell", CELL_CAPACITY), ("wide", WIDE_CAPACITY))}
    assert grew["wide"] > 2.0, grew  # the effect is there, and this measures it
    assert grew["cell"] < 1.0, grew


def test_an_ask_that_no_reply_came_to_is_said_asked_again_and_lets_no_neighbour_go(tmp_path):
    """A frozen (or stalled) router answers no ask: an agent that entered a cell then never knew the
    neighbour already there, and stopped guarding it once it fell silent (docs/experiments.md). An
    unanswered "who is here" ask is told apart from an empty cell (whose answer comes at once) and asked
    again; the cell is known only once an answer came, after its tokens. An ask of whether a doubted
    neighbour's member token is held that no reply came to lets nobody go; one answered empty does."""
    import signal

    from swarm_procs import freeze, processes
    from zswarm.host.procs import start_router
    from zswarm.net.keys import Keys
    from agents.membership import Membership

    keys = Keys("unanswered", 1.0)
    tags = lambda *wanted: [item for item in bridge.inbox if item[0] in wanted]  # noqa: E731
    ask = dict(unanswered="in-unanswered", answered="in-answered")
    with processes() as kids:
        endpoint = start_router(kids)
        router = kids.get("router")
        with zenoh.open(zenoh_config("client", connect=[endpoint])) as there, \
                zenoh.open(zenoh_config("client", connect=[endpoint])) as here:
            token = there.liveliness().declare_token(keys.member((0, 0), 2))  # agent 2 sits in cell (0, 0)
            bridge = Bridge(here, None, deliver=lambda item: None, batch=True)
            membership = Membership(keys, 4)
            membership.listen_to([(0, 0), (1, 0)], [])
            bridge.tokens_into_inbox(keys.cell_members((1, 0)), "in-now", 1.0, **ask)
            wait_until(lambda: tags("in-answered"), 5.0, "the empty cell's answer")
            assert [item[1] for item in tags("in-answered", "in-unanswered")] == [keys.cell_members((1, 0))]
            membership.answered(keys.cell_members((1, 0)))
            assert membership.known == {(1, 0)} and not membership.settled
            bridge.inbox.clear()
            freeze(router.proc.pid)
            try:
                bridge.token_absent_into_inbox(keys.member((0, 0), 2), "in-gone", 0.5)
                bridge.tokens_into_inbox(keys.cell_members((0, 0)), "in-now", 0.5, **ask)
                wait_until(lambda: tags("in-unanswered"), 5.0, "the unanswered ask")
            finally:
                router.proc.send_signal(signal.SIGCONT)
            said = tags("in-unanswered")
            assert [item[1] for item in said] == [keys.cell_members((0, 0))] and not tags("in-answered")
            membership.unanswered_ask(said[0][1])
            assert membership.unanswered == {keys.cell_members((0, 0))} and 2 not in membership.members
            for key in membership.unanswered:  # asked again, as agents.outreach does the next tick
                bridge.tokens_into_inbox(key, "in-now", 1.0, **ask)
            bridge.token_absent_into_inbox(keys.member((1, 0), 7), "in-gone", 1.0)  # nobody holds it
            wait_until(lambda: tags("in-answered") and tags("in-gone"), 5.0, "the answers")
            assert [item[0] for item in tags("in-now", "in-answered")] == ["in-now", "in-answered"]  # tokens first
            # the frozen router's absent check ran out long before: it said nothing
            assert [item[1] for item in tags("in-gone")] == [keys.member((1, 0), 7)]
            for tag, key, _, deleted, _ in list(bridge.inbox):
                if tag == "in-now":
                    membership.member(key, deleted, live=False)
                elif tag == "in-answered":
                    membership.answered(key)
            assert membership.members == {2: {(0, 0)}} and membership.settled
            token.undeclare()
            bridge.close()
