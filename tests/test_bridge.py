"""The bridge's ring-channel inbox, over real Zenoh sessions: what a free-running agent takes in."""

from __future__ import annotations

import time

import zenoh

from conftest import free_port
from zswarm.net.bridge import Bridge
from zswarm.net.config import zenoh_config


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
