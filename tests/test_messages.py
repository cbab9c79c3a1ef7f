"""Wire messages: round trips, and no input whatsoever makes decode raise anything but DecodeError."""

import math
import struct

import msgpack
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zswarm.net import histogram
from zswarm.net import messages as msg

finite = st.floats(-1e5, 1e5, allow_nan=False)
pose_fields = (st.integers(0, 10_000), st.integers(0, 2**40), st.floats(0, 2e9), st.integers(-1, 10**6),
               finite, finite, finite, finite, st.one_of(st.none(), st.floats(-3.15, 3.15)))  # heading last
nodes = st.integers(0, 0xFFFF)
poses = st.one_of(st.builds(msg.Pose, *pose_fields, z=st.none(), vz=st.none(), safety=st.integers(0, 3), node=nodes),
                  st.builds(msg.Pose, *pose_fields[:-1], heading=st.none(), z=finite, vz=finite,
                            safety=st.integers(0, 3), node=nodes))  # 2-D, 3-D (no heading in 3-D)
hist = st.dictionaries(st.integers(0, msg.MAX_HIST_BINS - 1), st.integers(0, 10**6), max_size=20)


def _stats(heard: list[tuple[int, int]], *fields, born: float | None = None) -> msg.Stats:
    """A Stats message whose heard ids and their pose counts line up."""
    return msg.Stats(*fields[:10], tuple(i for i, _ in heard), *fields[10:], heard_poses=tuple(n for _, n in heard),
                     born=born)


stats = st.builds(_stats,
                  st.lists(st.tuples(st.integers(0, 1000), st.integers(0, 10**6)), max_size=10),
                  st.integers(0, 1000), st.integers(0, 10**9), st.integers(0, 10**9),
                  st.dictionaries(st.sampled_from(msg.REASONS), st.integers(0, 100), max_size=3),
                  st.integers(0, 10**6), st.integers(0, 10**6), hist, hist, st.booleans(),
                  st.builds(msg.Health, *[st.integers(0, 10**9)] * 6, st.floats(0, 1e5)),
                  st.dictionaries(st.integers(0, 1000), st.floats(0, 2e9), max_size=3),
                  st.dictionaries(st.integers(0, 1000), st.floats(0, 2e9), max_size=3),
                  born=st.one_of(st.none(), st.floats(0, 2e9)))
messages = st.one_of(
    poses,
    st.builds(msg.Prey, st.integers(0, 2**40), st.floats(0, 2e9), st.integers(-1, 10**6), finite, finite,
              st.one_of(st.none(), finite)),
    st.builds(msg.Tick, st.integers(0, 10**6), st.floats(0, 2e9), finite, finite, st.one_of(st.none(), finite),
              final=st.booleans()),
    st.lists(st.tuples(finite, finite), max_size=20).map(lambda c: msg.Obstacles(tuple(c), tuple(0.5 for _ in c))),
    st.lists(st.tuples(finite, finite, finite), max_size=20).map(
        lambda c: msg.Obstacles(tuple(c), tuple(0.5 for _ in c), dims=3)),
    stats,
)


@settings(max_examples=300, deadline=None)
@given(m=messages)
def test_round_trip(m):
    assert msg.decode(msg.encode(m)) == m


def test_a_stats_message_carries_every_health_field():
    """Each field of Health gets its own value and comes back as sent (a field the encoder does not name
    would come back as its default)."""
    import dataclasses

    names = [f.name for f in dataclasses.fields(msg.Health)]
    health = msg.Health(**{name: (7.5 + k if name == "tick_lag_max_ms" else k + 1) for k, name in enumerate(names)})
    m = msg.Stats(3, 10, 20, {}, 0, 100, {1: 2}, {3: 4}, health=health)
    assert msg.decode(msg.encode(m)).health == health
    assert sorted(msg.HEALTH_FIELDS) == sorted(names)


@settings(max_examples=1000, deadline=None)
@given(data=st.binary(max_size=512))
def test_random_bytes_never_crash_the_decoder(data):
    try:
        msg.decode(data)
    except msg.DecodeError as exc:
        assert exc.reason in msg.REASONS


json_like = st.recursive(st.none() | st.booleans() | st.integers(-2**63, 2**64 - 1) | st.floats() | st.text(max_size=5),
                         lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=3), c, max_size=4),
                         max_leaves=20)


@settings(max_examples=1000, deadline=None)
@given(m=messages.filter(lambda m: not isinstance(m, msg.Pose)),
       key=st.sampled_from(["v", "k", "id", "seq", "t", "s", "p", "u", "c", "r", "ages", "h", "f"]), value=json_like)
def test_mutated_fields_are_rejected_or_valid(m, key, value):
    obj = msgpack.unpackb(msg.encode(m), raw=False, strict_map_key=False)
    obj[key] = value
    try:
        out = msg.decode(msgpack.packb(obj, use_bin_type=True))
    except msg.DecodeError as exc:
        assert exc.reason in msg.REASONS
    else:
        assert out is not None


@settings(max_examples=1000, deadline=None)
@given(m=poses, at=st.integers(0, 79), byte=st.integers(0, 255), cut=st.integers(0, 80))
def test_mutated_pose_records_are_rejected_or_valid(m, at, byte, cut):
    """Any byte of a pose record changed, or the record cut short: rejected by reason, or a Pose
    within every bound (the checks do not depend on which field the bytes fell in)."""
    data = bytearray(msg.encode(m))
    data[at % len(data)] = byte
    for payload in (bytes(data), bytes(data[:cut])):
        try:
            out = msg.decode(payload)
        except msg.DecodeError as exc:
            assert exc.reason in msg.REASONS
        else:
            assert isinstance(out, msg.Pose) and 0 <= out.id <= msg.MAX_ID and out.seq >= 0 and out.step >= -1
            assert all(math.isfinite(c) and abs(c) <= msg.MAX_COORD for c in (*out.position, *out.velocity))
            assert out.heading is None or abs(out.heading) <= msg.MAX_HEADING
            assert 0 <= out.safety < len(msg.SAFETY_FLAGS)


@settings(max_examples=300, deadline=None)
@given(ms=st.lists(poses, min_size=1, max_size=8), hits=st.lists(st.tuples(st.integers(0, 79), st.integers(0, 255)),
                                                              max_size=8))
def test_a_batch_of_records_decodes_as_each_record_alone(ms, hits):
    """decode_pose_records (the world's tick of poses in one call) takes exactly the records decode
    takes, with the same fields; mutated bytes included (each size in a batch of its own)."""
    data = [bytearray(msg.encode(m)) for m in ms]
    for k, (at, byte) in enumerate(hits):
        d = data[k % len(data)]
        d[at % len(d)] = byte
    for size in {len(d) for d in data}:
        same = [bytes(d) for d in data if len(d) == size]
        rows, ok = msg.decode_pose_records(same)
        for payload, row, took in zip(same, rows, ok):
            try:
                alone = msg.decode(payload)
            except msg.DecodeError:
                alone = None
            assert took == isinstance(alone, msg.Pose), (payload, row)
            if took:
                z = alone.z is not None
                assert (int(row["id"]), int(row["seq"]), float(row["t"]), int(row["s"]), int(row["f"]),
                        int(row["n"])) == (alone.id, alone.seq, alone.stamp, alone.step, alone.safety, alone.node)
                assert (float(row["x"]), float(row["y"]), float(row["vx"]), float(row["vy"])) == (
                    alone.x, alone.y, alone.vx, alone.vy)
                assert (float(row["z"]), float(row["vz"])) == (alone.z, alone.vz) if z else alone.z is None
                if "h" in row.dtype.names:
                    assert float(row["h"]) == alone.heading


#: Each field of a pose record with values at and beyond its bounds (the first is a valid one).
EDGES = {"magic": [0xC1, 0xC0], "v": [msg.VERSION, msg.VERSION + 1, msg.VERSION - 1], "flags": [None, 0, 1, 2, 3],
         "f": [0, 3, 4, 5], "i": [7, 0, msg.MAX_ID, msg.MAX_ID + 1], "seq": [9, 0, -1, 2**62, 2**62 + 1],
         "s": [-1, -2, 0, msg.MAX_STEP, -2**31], "n": [3, 0, 0xFFFF], "spare": [0, 1, 0xFFFF], "t": [0.0, 1e12, -1e12, 1.1e12, -1.1e12, math.nan, math.inf],
         **{f"c{k}": [0.5, msg.MAX_COORD, -msg.MAX_COORD, 1.1e6, -1.1e6, math.nan, -math.inf, 7.0, -7.0, 7.5, -7.5]
            for k in range(6)}}


@settings(max_examples=600, deadline=None)
@given(size=st.sampled_from(sorted(msg.POSE_ROWS)), field=st.sampled_from(sorted(EDGES)), pick=st.integers(0, 10))
def test_every_bound_of_a_batch_of_records_as_decode_has_it(size, field, pick):
    """The same, a valid record with one field at or beyond a bound (a random byte seldom lands on one)."""
    n = (size - 32) // 8
    values = {k: v[0] for k, v in EDGES.items()}
    values["flags"] = {64: 0, 72: msg.POSE_HEADING, 80: msg.POSE_3D}[size]
    if field != "flags":
        values[field] = EDGES[field][pick % len(EDGES[field])]
    else:
        values["flags"] = EDGES["flags"][1 + pick % 4]
    payload = struct.pack(msg.POSE_LAYOUT + "d" * n, values["magic"], values["v"], values["flags"], values["f"],
                          values["i"], values["seq"], values["t"], values["s"], values["n"], values["spare"],
                          *(values[f"c{k}"] for k in range(n)))
    rows, ok = msg.decode_pose_records([payload])
    try:
        alone = msg.decode(payload)
    except msg.DecodeError:
        alone = None
    assert bool(ok[0]) == isinstance(alone, msg.Pose), (field, values)


V = msg.VERSION


def record(i=1, seq=1, t=0.0, s=-1, x=0.0, y=0.0, vx=0.0, vy=0.0, *, v=V, flags=0, f=0, node=0, extra=()) -> bytes:
    """A 2-D pose record built field by field from :data:`messages.POSE_LAYOUT` (unchecked)."""
    fmt = msg.POSE_LAYOUT + "d" * (4 + len(extra))
    return struct.pack(fmt, 0xC1, v, flags, f, i, seq, t, s, node, 0, x, y, vx, vy, *extra)


@pytest.mark.parametrize("payload,reason", [
    (record(v=V + 1), "version"),
    (record(x=math.nan), "nonfinite"),
    (record(x=math.inf), "nonfinite"),
    (record(vy=-math.inf), "nonfinite"),
    (record(x=1e9), "range"),
    (record(t=1e13), "range"),
    (record(i=msg.MAX_ID + 1), "range"),
    (record(s=-2), "range"),
    (record(seq=-1), "range"),
    (record(f=len(msg.SAFETY_FLAGS)), "range"),
    (record(flags=msg.POSE_3D), "schema"),                          # a 2-D record flagged 3-D
    (record(extra=(math.nan,), flags=msg.POSE_HEADING), "nonfinite"),  # its heading
    (record(extra=(100.0,), flags=msg.POSE_HEADING), "range"),
    (record()[:-3], "malformed"),
    (record() + b"\0", "malformed"),
    (b"\xc1", "malformed"),
])
def test_specific_pose_rejections(payload, reason):
    with pytest.raises(msg.DecodeError) as err:
        msg.decode(payload)
    assert err.value.reason == reason


@pytest.mark.parametrize("obj,reason", [
    ({"v": V + 1, "k": "prey"}, "version"),
    ({"v": V - 1, "k": "pose", "id": 1, "seq": 1, "t": 0.0, "s": -1, "p": [0.0, 0.0], "u": [0, 0]}, "version"),
    ({"v": V, "k": "teleport"}, "kind"),
    ({"v": V, "k": "pose", "id": 1, "seq": 1, "t": 0.0, "s": -1, "p": [0.0, 0.0], "u": [0, 0]}, "kind"),
    ({"v": V, "k": "prey", "seq": 1, "t": 0.0, "s": -1, "p": [math.nan, 0.0]}, "nonfinite"),
    ({"v": V, "k": "prey", "seq": 1, "t": 0.0, "s": -1, "p": [1e9, 0.0]}, "range"),
    ({"v": V, "k": "prey", "seq": True, "t": 0.0, "s": -1, "p": [0.0, 0.0]}, "schema"),
    ({"v": V, "k": "prey", "seq": 1, "t": 0.0, "s": -1, "p": [0.0, 0.0, 0.0, 0.0]}, "schema"),
    ({"v": V, "k": "obst", "c": [[0, 0]], "r": [1.0], "d": 3}, "schema"),
    ({"v": V, "k": "obst", "c": [], "r": [], "d": 4}, "range"),
    ({"v": V, "k": "obst", "c": [[0, 0]] * (msg.MAX_OBSTACLES + 1), "r": [0] * (msg.MAX_OBSTACLES + 1)}, "size"),
    ({"v": V, "k": "obst", "c": [[0, 0]], "r": [-1.0]}, "range"),
    ([1, 2, 3], "malformed"),
])
def test_specific_rejections(obj, reason):
    with pytest.raises(msg.DecodeError) as err:
        msg.decode(msgpack.packb(obj, use_bin_type=True))
    assert err.value.reason == reason


def test_a_pose_is_a_fixed_record_and_names_its_encoding():
    for pose, size in ((msg.Pose(1, 1, 0.0, -1, 0.0, 0.0, 0.0, 0.0), 64),
                       (msg.Pose(1, 1, 0.0, -1, 0.0, 0.0, 0.0, 0.0, 1.0), 72),
                       (msg.Pose(1, 1, 0.0, -1, 0.0, 0.0, 0.0, 0.0, None, 0.0, 0.0), 80)):
        data = msg.encode(pose)
        assert len(data) == size and data[:1] == b"\xc1" and msg.encoding_of(data) == msg.POSE_ENCODING
    assert msg.encoding_of(msg.encode(msg.Prey(1, 0.0, -1, 0.0, 0.0))) == msg.ENCODING
    with pytest.raises(ValueError):
        msg.encode(msg.Pose(1, 1, 0.0, -1, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0))  # 3-D has no heading


def test_oversized_and_truncated_payloads():
    with pytest.raises(msg.DecodeError) as err:
        msg.decode(b"\x00" * (msg.MAX_PAYLOAD + 1))
    assert err.value.reason == "size"
    good = msg.encode(msg.Prey(1, 0.0, -1, 0.0, 0.0))
    with pytest.raises(msg.DecodeError) as err:
        msg.decode(good[:-3])
    assert err.value.reason == "malformed"


def test_histogram_percentiles():
    h = {}
    for ms in range(1, 101):  # 1..100 ms
        b = histogram.to_bin(float(ms))
        h[b] = h.get(b, 0) + 1
    assert histogram.percentile(h, 0.5) == pytest.approx(50.75, abs=1.0)
    assert histogram.percentile(h, 0.99) == pytest.approx(99.75, abs=1.0)
    assert histogram.percentile({}, 0.5) is None
    assert histogram.merge([{1: 2}, {1: 3, 4: 1}]) == {1: 5, 4: 1}
