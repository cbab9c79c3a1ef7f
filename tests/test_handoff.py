"""An agent's state handed from the process that ran it to the one that takes it over (agents.handoff)."""

from __future__ import annotations

import dataclasses

import msgpack
import pytest

from agents.counters import Counters
from agents.handoff import HandoffError, apply_state, encode_state
from agents.sensing import Body
from zswarm.net.poses import Rejections


def busy_counters() -> Counters:
    c = Counters(Rejections("agent 3"))
    c.sent, c.received, c.poses, c.crossed, c.ticks, c.late_ticks = 400, 1200, 1100, 300, 401, 7
    c.interventions, c.stalled_ticks, c.braked_ticks, c.stalled_long = 5, 2, 1, True
    c.ages, c.latency, c.heard = {3: 10, 40: 2}, {1: 900, 2: 200}, {1: 500, 7: 600}
    c.seq_received, c.seq_lost = 1000, 3
    c.departed, c.returned = {7: 12.5}, {7: 13.0}
    c.rejections.counts.update({"range": 2})
    return c


@pytest.mark.parametrize("body", [Body(1.5, -2.0, 0.3, 0.4, step=812), Body(1.0, 2.0, step=3, heading=0.7),
                                  Body(1.0, 2.0, 0.1, 0.2, step=9, z=3.0, vz=-0.1)])
def test_the_state_carries_the_body_the_sequence_and_every_counter(body):
    old = busy_counters()
    payload = encode_state(body, 4711, old)
    new_body = Body(0.0, 0.0, z=None if body.z is None else 0.0)
    new = Counters(Rejections("agent 3"))
    new.rejections.counts["kind"] = 1  # what the new process refused while it waited
    assert apply_state(payload, new_body, new) == 4711
    assert new_body == body
    for f in dataclasses.fields(Counters):
        if f.name != "rejections":
            assert getattr(new, f.name) == getattr(old, f.name), f.name
    assert new.rejections.counts == {"range": 2, "kind": 1}


def test_a_malformed_or_foreign_state_is_refused_and_changes_nothing():
    body, counters = Body(1.0, 1.0, step=5), Counters(Rejections("agent 1"))
    good = encode_state(Body(2.0, 2.0, step=9), 10, busy_counters())
    three_d = encode_state(Body(2.0, 2.0, z=1.0, vz=0.0), 10, busy_counters())
    state = msgpack.unpackb(good, strict_map_key=False)

    def changed(part: str, name: str, value) -> bytes:
        return msgpack.packb({**state, part: {**state[part], name: value}}, use_bin_type=True)

    bad = [b"\x00\x01garbage", msgpack.packb({"k": "pose"}), good[: len(good) // 2],
           msgpack.packb({**state, "seq": "x"}, use_bin_type=True), changed("body", "x", "1.0"),
           changed("body", "y", float("nan")), changed("body", "step", 1.5), changed("counters", "ticks", "7"),
           changed("counters", "ages", [1, 2]), changed("counters", "heard", {"a": 1})]
    for payload in bad:
        with pytest.raises(HandoffError):
            apply_state(payload, body, counters)
    with pytest.raises(HandoffError, match="3-D state for a 2-D agent"):
        apply_state(three_d, body, counters)
    assert body == Body(1.0, 1.0, step=5) and counters == Counters(Rejections("agent 1"))


def test_the_world_keeps_a_final_report_over_an_older_message_that_arrives_after_it():
    """A moved agent's old process's last message can arrive after the new one's final report (another
    path), and an agent's last periodic message (batched) after its final report (express): a final
    report is replaced only by one with more ticks; otherwise the newest is the agent's (a restarted
    agent counts anew); a report that does not decode is counted and the good one kept."""
    from world.report import StatsBook
    from zswarm.net import messages as msg
    from zswarm.net.keys import Keys

    def stats(ticks: int, final: bool) -> bytes:
        c = Counters(Rejections("agent 4"))
        c.ticks = ticks
        return msg.encode(c.stats(4, 0.05, final=final))

    rejected = Rejections("world")
    book = StatsBook(Keys.agent_of, rejected)
    key = "zswarm/r/stats/4"
    for payload in (stats(100, False), stats(480, True), stats(470, False), b"\x01junk", stats(480, False),
                    stats(0, True)):
        book.add(key, payload)
    got = book.get(4)
    assert got.ticks == 480 and got.final and book.final(4)
    assert rejected.total == 1
    for t in range(20):  # a long run: what is not read yet stays bounded
        book.add(key, stats(500 + t, False))
    assert len(book.raw.get(4, [])) <= 8 and book.get(4).ticks == 519 and not book.final(4)
    book.add(key, stats(12, False))  # killed and restarted: its counts begin anew
    assert book.get(4).ticks == 12
