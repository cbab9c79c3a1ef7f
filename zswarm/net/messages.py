"""Every wire message, encoded and decoded in one place, versioned and validated.

A pose, the message every agent sends and hears every tick, is a fixed little-endian record
(:data:`POSE_LAYOUT`, 64 bytes in 2-D) that opens with the byte 0xC1, which msgpack never uses, so it
cannot be taken for anything else; it is unpacked in one call. Every other message is a msgpack map
with ``v`` (format version) and ``k`` (kind). Positions and velocities are two numbers in a 2-D run
and three in a 3-D one (``p``, ``u``; an obstacle answer says ``d``: 3); a process refuses a message of
the other dimension with the reason ``dimensions``, so a 2-D agent and a 3-D world never mix silently.
Decoding never trusts the bytes: a payload that is too large, not msgpack (nor a pose record), of an
unknown version or kind, with missing or mistyped fields, non-finite numbers or out-of-range sizes
raises :class:`DecodeError`, whose ``reason`` is one of :data:`REASONS` (processes count rejections
by reason).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any, NamedTuple, Sequence, Union

import msgpack
import numpy as np

VERSION = 3  # 3: a pose names the router it entered on; 2: poses are fixed binary records (1: msgpack maps)
#: The Zenoh encoding every zswarm payload but a pose is published with: generic Zenoh tools (z_sub,
#: z_get) can tell it is msgpack, and of which zswarm schema version.
ENCODING = f"application/msgpack;zswarm/{VERSION}"
#: The encoding of a pose (:data:`POSE_LAYOUT`).
POSE_ENCODING = f"application/octet-stream;zswarm/{VERSION}/pose"
MAX_PAYLOAD = 256 * 1024
MAX_OBSTACLES = 4096
MAX_ID = 1_000_000
MAX_COORD = 1e6  # |x|, |y|, |z| beyond this is rejected as impossible
MAX_HEADING = 7.0  # |heading| in radians: an agent sends it in [-pi, pi)
MAX_HIST_BINS = 20_000
MAX_HEARD = 4096

REASONS = ("size", "malformed", "version", "kind", "schema", "nonfinite", "range", "dimensions")


def point(x: float, y: float, z: float | None) -> tuple[float, ...]:
    """(x, y), or (x, y, z) in a 3-D run (z is None in 2-D): a position or a velocity."""
    return (x, y) if z is None else (x, y, z)


class DecodeError(ValueError):
    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


class Pose(NamedTuple):
    """An agent's state: id, sequence number, sender wall time, lockstep step (-1 if free), x, y, vx, vy,
    its heading in radians where its body has one (:mod:`zswarm.control.body`; None otherwise), and in a
    3-D run z and vz (None in 2-D).

    Immutable like the other messages, but a named tuple rather than a frozen dataclass: an agent
    builds one for every pose it hears, and a tuple is built in a sixth of the time."""

    id: int
    seq: int
    stamp: float
    step: int
    x: float
    y: float
    vx: float
    vy: float
    heading: float | None = None
    z: float | None = None
    vz: float | None = None
    safety: int = 0  # what the safety filter did to the command it moved with: SAFETY_FLAGS
    node: int = 0  # the index of the router its sender is connected to (POSE_LAYOUT)

    @property
    def dims(self) -> int:
        return 2 if self.z is None else 3

    @property
    def position(self) -> tuple[float, ...]:
        return point(self.x, self.y, self.z)

    @property
    def velocity(self) -> tuple[float, ...]:
        return point(self.vx, self.vy, self.vz)


class Prey(NamedTuple):
    """The prey as the world publishes it (a named tuple, as :class:`Pose`: every agent decodes one a
    tick); z in a 3-D run."""

    seq: int
    stamp: float
    step: int
    x: float
    y: float
    z: float | None = None

    @property
    def position(self) -> tuple[float, ...]:
        return point(self.x, self.y, self.z)


@dataclass(frozen=True)
class Tick:
    """Lockstep: step ``step`` begins; the prey is at (x, y) (and z in a 3-D run). ``final``: the run
    ends after it."""

    step: int
    stamp: float
    x: float
    y: float
    z: float | None = None
    final: bool = False

    @property
    def position(self) -> tuple[float, ...]:
        return point(self.x, self.y, self.z)


@dataclass(frozen=True)
class Obstacles:
    """The world's answer to an obstacle query: centres (pairs, or triples in 3-D), radii, and the
    run's dimension (also when no obstacle is near)."""

    centers: tuple[tuple[float, ...], ...]
    radii: tuple[float, ...]
    dims: int = 2


@dataclass(frozen=True)
class Health:
    """An agent's own counters beside its traffic: failed obstacle queries, poses counted and lost by
    sequence number (observed loss), injected faults, and over the last stats period the longest
    inbound queue at a tick and the latest a tick started."""

    obstacle_queries_failed: int = 0
    seq_received: int = 0
    seq_lost: int = 0
    injected_drops: int = 0
    injected_passed: int = 0
    queue_max: int = 0
    tick_lag_max_ms: float = 0.0
    poses: int = 0  # other agents' poses taken in (however they arrived)
    # the safety filter (zswarm.swarm.tally): ticks it changed the command, left it under a
    # tenth of the law's speed, and braked on data too old
    interventions: int = 0
    stalled_ticks: int = 0
    braked_ticks: int = 0
    stalled_long: int = 0  # 1: stalled for a second or more in a row at some point
    crossed: int = 0  # of ``poses``, those sent from another router (Pose.node is not its own)
    skipped_ticks: int = 0  # free clock: the ticks a late agent let go by (its schedule moves on; no backlog)


HEALTH_INTS = ("obstacle_queries_failed", "seq_received", "seq_lost", "injected_drops", "injected_passed",
               "queue_max", "poses", "interventions", "stalled_ticks", "braked_ticks",
               "stalled_long", "crossed", "skipped_ticks")
HEALTH_FIELDS = (*HEALTH_INTS, "tick_lag_max_ms")  # every field of Health, as the stats map carries them


@dataclass(frozen=True)
class Stats:
    """An agent's cumulative counters and histograms (0.5 ms bins) of the age of neighbour data when it
    was used, and of the one-way latency (publish to receipt) of the poses it received."""

    id: int
    sent: int
    received: int
    rejected: dict[str, int]
    late_ticks: int
    ticks: int
    age_hist: dict[int, int]
    latency_hist: dict[int, int]
    final: bool = False
    health: Health = Health()
    heard: tuple[int, ...] = ()  # ids whose poses it has received (at most MAX_HEARD)
    departed: dict[int, float] | None = None  # id -> wall time it first dropped that neighbour
    returned: dict[int, float] | None = None  # id -> wall time a dropped neighbour was first heard again
    heard_poses: tuple[int, ...] = ()  # how many poses of each id in ``heard`` it took in (same order)
    born: float | None = None  # wall time the reporting process started (it may have outlived a departure)


Message = Union[Pose, Prey, Tick, Obstacles, Stats]


def _pack(obj: dict[str, Any]) -> bytes:
    return msgpack.packb({"v": VERSION, **obj}, use_bin_type=True)


def encoding_of(payload: bytes) -> str:
    """The Zenoh encoding to publish ``payload`` with (a pose record or a msgpack map)."""
    return POSE_ENCODING if payload[:1] == POSE_MAGIC else ENCODING


#: A pose on the wire, little-endian, no padding: the byte 0xC1 (never a msgpack byte), the version,
#: flags (1: 3-D, 2: a heading follows), the safety flag, id (uint32), seq (int64), stamp (double,
#: sender wall time), step (int32, -1 free), node (uint16: the index of the router its sender is
#: connected to, for counting the poses that crossed between routers), two bytes spare (0), then
#: doubles: x, y, vx, vy (2-D), x, y, z, vx, vy, vz (3-D), and the heading last where flagged. 64
#: bytes in 2-D, 72 with a heading, 80 in 3-D.
POSE_LAYOUT = "<BBBBIqdiHH"
MAX_STEP = 2**31 - 1
POSE_MAGIC = b"\xc1"
POSE_3D, POSE_HEADING = 1, 2
_POSE_2D = struct.Struct(POSE_LAYOUT + "4d")
_POSE_2DH = struct.Struct(POSE_LAYOUT + "5d")
_POSE_3D = struct.Struct(POSE_LAYOUT + "6d")
_POSE_LAYOUTS = {layout.size: layout for layout in (_POSE_2D, _POSE_2DH, _POSE_3D)}
POSE_SIZES = tuple(_POSE_LAYOUTS)

#: A pose's ``f``: the safety filter (zswarm.control.safety) passed the command, changed it, stalled it, braked.
SAFETY_FLAGS = ("passed", "acted", "stalled", "braked")
N_FLAGS = len(SAFETY_FLAGS)


def encode_pose(agent: int, seq: int, stamp: float, step: int, x: float, y: float, vx: float, vy: float,
                heading: float | None = None, z: float | None = None, vz: float | None = None,
                safety: int = 0, node: int = 0) -> bytes:
    """``encode(Pose(...))`` without building the Pose: an agent publishes one every tick
    (:data:`POSE_LAYOUT`). A 3-D pose has no heading."""
    if z is None:
        if heading is None:
            return _POSE_2D.pack(0xC1, VERSION, 0, safety, agent, seq, stamp, step, node, 0, x, y, vx, vy)
        return _POSE_2DH.pack(0xC1, VERSION, POSE_HEADING, safety, agent, seq, stamp, step, node, 0,
                              x, y, vx, vy, heading)
    if heading is not None:
        raise ValueError("a 3-D pose has no heading")
    return _POSE_3D.pack(0xC1, VERSION, POSE_3D, safety, agent, seq, stamp, step, node, 0, x, y, z, vx, vy, vz)


#: Each record layout as a numpy row (the same bytes, no padding), by size: a receiver of many poses
#: reads a batch of records of one size in one call (:func:`decode_pose_records`).
POSE_ROWS = {size: np.dtype([("magic", "u1"), ("v", "u1"), ("flags", "u1"), ("f", "u1"), ("id", "<u4"),
                             ("seq", "<i8"), ("t", "<f8"), ("s", "<i4"), ("n", "<u2"), ("spare", "<u2"),
                             *((name, "<f8") for name in names)])
             for size, names in ((_POSE_2D.size, ("x", "y", "vx", "vy")),
                                 (_POSE_2DH.size, ("x", "y", "vx", "vy", "h")),
                                 (_POSE_3D.size, ("x", "y", "z", "vx", "vy", "vz")))}
_ROW_FLAGS = {_POSE_2D.size: 0, _POSE_2DH.size: POSE_HEADING, _POSE_3D.size: POSE_3D}
#: The record sizes of a run of each dimension (2-D: without and with a heading).
POSE_SIZES_BY_DIMS = {2: (_POSE_2D.size, _POSE_2DH.size), 3: (_POSE_3D.size,)}


def decode_pose_records(payloads: Sequence[bytes]) -> tuple[np.ndarray, np.ndarray]:
    """Pose records of one size (a key of :data:`POSE_ROWS`) at once: the rows, and which of them
    :func:`decode` takes as they are. The checks are :func:`_pose`'s (``tests/test_messages.py`` holds
    the two equal); a row that fails them goes to :func:`decode`, which says what is wrong."""
    size = len(payloads[0]) if payloads else _POSE_2D.size
    rows = np.frombuffer(b"".join(payloads), dtype=POSE_ROWS[size])
    if len(rows) != len(payloads):
        raise ValueError("pose records of one size only")
    ok = ((rows["magic"] == POSE_MAGIC[0]) & (rows["v"] == VERSION) & (rows["flags"] == _ROW_FLAGS[size])
          & (rows["f"] < N_FLAGS) & (rows["id"] <= MAX_ID) & (rows["seq"] >= 0) & (rows["seq"] <= 2**62)
          & (rows["s"] >= -1) & (rows["t"] >= -1e12) & (rows["t"] <= 1e12))
    for name in POSE_ROWS[size].names[10:]:  # NaN fails these, as it fails _pose's
        bound = MAX_HEADING if name == "h" else MAX_COORD
        ok &= (rows[name] >= -bound) & (rows[name] <= bound)
    return rows, ok


def encode_positions(t: float, ids: np.ndarray, positions: np.ndarray) -> bytes:
    """Where the world last saw each live agent, at its clock's ``t`` (the world's ``keys.positions``)."""
    return _pack({"k": "positions", "t": float(t), "ids": np.asarray(ids, dtype=np.int64).tolist(),
                  "p": np.asarray(positions, dtype=float).ravel().tolist(), "d": int(np.shape(positions)[-1])})


def decode_positions(payload: bytes) -> tuple[float, np.ndarray, np.ndarray]:
    """(t, ids, positions (N x D)) of :func:`encode_positions`; :class:`DecodeError` if malformed."""
    try:
        obj = msgpack.unpackb(payload, raw=False)
        ids = np.asarray(obj["ids"], dtype=np.int64)
        pos = np.asarray(obj["p"], dtype=float).reshape(len(ids), int(obj["d"]))
        return float(obj["t"]), ids, pos
    except Exception as exc:  # noqa: BLE001
        raise DecodeError("malformed", f"a positions message ({type(exc).__name__}: {exc})") from None


def encode(msg: Message) -> bytes:
    if isinstance(msg, Pose):
        return encode_pose(*msg)
    if isinstance(msg, Prey):
        return _pack({"k": "prey", "seq": msg.seq, "t": msg.stamp, "s": msg.step, "p": list(msg.position)})
    if isinstance(msg, Tick):
        return _pack({"k": "tick", "s": msg.step, "t": msg.stamp, "p": list(msg.position), "f": msg.final})
    if isinstance(msg, Obstacles):
        extra = {} if msg.dims == 2 else {"d": msg.dims}
        return _pack({"k": "obst", "c": [list(c) for c in msg.centers], "r": list(msg.radii), **extra})
    if isinstance(msg, Stats):
        # once a second from every agent, on its control thread: plain copies (dataclasses.asdict deep-
        # copies field by field; docs/benchmarks.md)
        health = msg.health
        return _pack({"k": "stats", "id": msg.id, "sent": msg.sent, "recv": msg.received,
                      "rej": dict(msg.rejected), "late": msg.late_ticks, "ticks": msg.ticks,
                      "ages": dict(msg.age_hist), "lat": dict(msg.latency_hist), "f": msg.final,
                      "x": {name: getattr(health, name) for name in HEALTH_FIELDS}, "h": list(msg.heard[:MAX_HEARD]),
                      "hn": list(msg.heard_poses[:MAX_HEARD]),
                      "dep": dict(msg.departed or {}), "ret": dict(msg.returned or {}),
                      **({} if msg.born is None else {"b": msg.born})})
    raise TypeError(f"cannot encode {type(msg).__name__}")


# --- decoding -------------------------------------------------------------------------------------------

def _int(d: dict, key: str, lo: int = 0, hi: int = 2**62) -> int:
    v = d.get(key)
    if type(v) is int and lo <= v <= hi:  # the common case, at once (an agent decodes every pose it hears)
        return v
    if not isinstance(v, int) or isinstance(v, bool):
        raise DecodeError("schema", f"{key} must be an integer")
    if not lo <= v <= hi:
        raise DecodeError("range", f"{key}={v} outside [{lo}, {hi}]")
    return v


def _float(v: Any, key: str, bound: float = MAX_COORD) -> float:
    if type(v) is float and -bound <= v <= bound:  # finite and in range (NaN fails both comparisons)
        return v
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise DecodeError("schema", f"{key} must be a number")
    v = float(v)
    if not math.isfinite(v):
        raise DecodeError("nonfinite", f"{key} is {v}")
    if abs(v) > bound:
        raise DecodeError("range", f"|{key}| = {abs(v):g} > {bound:g}")
    return v


def _vec(d: dict, key: str, dims: tuple[int, ...] = (2, 3)) -> tuple[float, ...]:
    """A point: two numbers (2-D) or three (3-D), of the lengths ``dims`` allows."""
    v = d.get(key)
    if not isinstance(v, (list, tuple)) or len(v) not in dims:
        what = " or ".join({2: "a pair", 3: "a triple"}[n] for n in dims)
        raise DecodeError("schema", f"{key} must be {what} of numbers")
    return tuple(_float(c, key) for c in v)


def _counts(v: Any, key: str, max_items: int) -> dict:
    if not isinstance(v, dict) or len(v) > max_items:
        raise DecodeError("schema", f"{key} must be a map of at most {max_items} counts")
    for name, count in v.items():
        if not isinstance(name, (str, int)) or isinstance(count, bool) or not isinstance(count, int) or count < 0:
            raise DecodeError("schema", f"{key} holds a bad entry")
    return dict(v)


def _times(v: Any, key: str) -> dict[int, float]:
    if not isinstance(v, dict) or len(v) > MAX_HEARD:
        raise DecodeError("schema", f"{key} must be a map of agent ids to times")
    out = {}
    for k, t in v.items():
        if not isinstance(k, int) or isinstance(k, bool) or not 0 <= k <= MAX_ID:
            raise DecodeError("schema", f"{key} keys must be agent ids")
        out[k] = _float(t, key, 1e12)
    return out


def _health(v: Any) -> Health:
    if not isinstance(v, dict) or len(v) > 64:
        raise DecodeError("schema", "x must be a small map")
    known = {k: v[k] for k in HEALTH_INTS if k in v}
    for k, n in known.items():
        if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= 2**62:
            raise DecodeError("schema", f"x.{k} must be a count")
    lag = _float(v.get("tick_lag_max_ms", 0.0), "x.tick_lag_max_ms", 1e12)
    return Health(**known, tick_lag_max_ms=lag)


def _bins(counts: dict) -> dict[int, int]:
    return {int(k): int(v) for k, v in counts.items() if isinstance(k, int) and 0 <= k < MAX_HIST_BINS}


def is_final_report(data: bytes) -> bool:
    """Whether ``data`` is an agent's final report (stats with ``final`` set), read without validating
    the rest (7 us, not decode's 60: the world looks at every stats message as it arrives). False for
    anything that is not one, malformed included."""
    try:
        obj = msgpack.unpackb(data, raw=False, strict_map_key=False)
    except Exception:  # noqa: BLE001 - anything malformed is not a final report
        return False
    return isinstance(obj, dict) and obj.get("k") == "stats" and obj.get("f") is True


def decode(data: bytes) -> Message:
    """Parse and validate one message; raises :class:`DecodeError` for anything unacceptable."""
    if len(data) > MAX_PAYLOAD:
        raise DecodeError("size", f"{len(data)} bytes > {MAX_PAYLOAD}")
    if data[:1] == POSE_MAGIC:
        return _pose(data)
    try:
        obj = msgpack.unpackb(data, raw=False, strict_map_key=False, max_bin_len=MAX_PAYLOAD,
                              max_str_len=MAX_PAYLOAD, max_array_len=2 * MAX_OBSTACLES + 16,
                              max_map_len=MAX_HIST_BINS + 16)
    except Exception as exc:  # msgpack raises many types for garbage
        raise DecodeError("malformed", f"not msgpack ({type(exc).__name__})") from None
    if not isinstance(obj, dict):
        raise DecodeError("malformed", "not a map")
    if obj.get("v") != VERSION:
        raise DecodeError("version", f"version {obj.get('v')!r}, expected {VERSION}")
    kind = obj.get("k")
    if kind == "pose":
        raise DecodeError("kind", f"a pose as a msgpack map (zswarm/{VERSION} sends poses as records)")
    if kind == "prey":
        return _prey(obj)
    return _other(obj, kind)


def _prey(obj: dict) -> Prey:
    """A prey map, checked as :func:`_pose` checks a pose."""
    seq, t, s, p = obj.get("seq"), obj.get("t"), obj.get("s"), obj.get("p")
    if type(seq) is int and type(t) is float and type(s) is int and type(p) is list and len(p) == 2:
        x, y = p
        if (type(x) is float and type(y) is float and 0 <= seq <= 2**62 and -1 <= s <= 2**62
                and -1e12 <= t <= 1e12 and -MAX_COORD <= x <= MAX_COORD and -MAX_COORD <= y <= MAX_COORD):
            return Prey(seq, t, s, x, y)
    return Prey(_int(obj, "seq"), _float(obj.get("t"), "t", 1e12), _int(obj, "s", -1), *_vec(obj, "p"))


def _pose(data: bytes) -> Pose:
    """A pose record (:data:`POSE_LAYOUT`): a well-formed one (every agent hears a few every tick) is
    checked in one pass; anything else field by field, to say what is wrong."""
    n = len(data)
    layout = _POSE_LAYOUTS.get(n)
    if layout is None:
        raise DecodeError("malformed", f"a pose record of {n} bytes (expected {', '.join(map(str, POSE_SIZES))})")
    _, v, flags, f, i, seq, t, s, node, _spare, *rest = layout.unpack(data)
    if layout is _POSE_2D:
        x, y, vx, vy = rest
        if (v == VERSION and flags == 0 and f < N_FLAGS and i <= MAX_ID and 0 <= seq <= 2**62 and -1 <= s
                and -1e12 <= t <= 1e12 and -MAX_COORD <= x <= MAX_COORD and -MAX_COORD <= y <= MAX_COORD
                and -MAX_COORD <= vx <= MAX_COORD and -MAX_COORD <= vy <= MAX_COORD):  # NaN fails these
            return Pose(i, seq, t, s, x, y, vx, vy, None, None, None, f, node)
    elif (v == VERSION and f < N_FLAGS and i <= MAX_ID and 0 <= seq <= 2**62 and -1 <= s and -1e12 <= t <= 1e12
          and all(-MAX_COORD <= c <= MAX_COORD for c in rest)):
        if layout is _POSE_3D and flags == POSE_3D:
            x, y, z, vx, vy, vz = rest
            return Pose(i, seq, t, s, x, y, vx, vy, None, z, vz, f, node)
        if layout is _POSE_2DH and flags == POSE_HEADING and -MAX_HEADING <= rest[4] <= MAX_HEADING:
            return Pose(i, seq, t, s, *rest, safety=f, node=node)
    if v != VERSION:
        raise DecodeError("version", f"version {v}, expected {VERSION}")
    want = {_POSE_2D: 0, _POSE_2DH: POSE_HEADING, _POSE_3D: POSE_3D}[layout]
    if flags != want:
        raise DecodeError("schema", f"flags {flags} in a pose record of {n} bytes (expected {want})")
    fields = {"id": i, "seq": seq, "s": s, "f": f}
    bounds = {"id": (0, MAX_ID), "seq": (0, 2**62), "s": (-1, MAX_STEP), "f": (0, len(SAFETY_FLAGS) - 1)}
    for key, (lo, hi) in bounds.items():
        _int(fields, key, lo, hi)
    _float(t, "t", 1e12)
    names = ("x", "y", "vx", "vy", "h") if layout is not _POSE_3D else ("x", "y", "z", "vx", "vy", "vz")
    c = [_float(value, key, MAX_HEADING if key == "h" else MAX_COORD) for key, value in zip(names, rest)]
    if layout is _POSE_3D:
        return Pose(i, seq, t, s, c[0], c[1], c[3], c[4], None, c[2], c[5], f, node)
    return Pose(i, seq, t, s, *c[:4], c[4] if len(c) == 5 else None, safety=f, node=node)


def _other(obj: dict, kind: Any) -> Message:
    """Every kind but the pose and the prey."""
    if kind == "tick":
        p = _vec(obj, "p")
        final = obj.get("f", False)
        if not isinstance(final, bool):
            raise DecodeError("schema", "f must be a boolean")
        return Tick(_int(obj, "s"), _float(obj.get("t"), "t", 1e12), *p, final=final)
    if kind == "obst":
        centers, radii = obj.get("c"), obj.get("r")
        if not isinstance(centers, list) or not isinstance(radii, list) or len(centers) != len(radii):
            raise DecodeError("schema", "c and r must be lists of equal length")
        if len(centers) > MAX_OBSTACLES:
            raise DecodeError("size", f"{len(centers)} obstacles > {MAX_OBSTACLES}")
        dims = _int(obj, "d", 2, 3) if "d" in obj else 2
        cs = tuple(_vec({"c": c}, "c", (dims,)) for c in centers)
        rs = tuple(_float(r, "r") for r in radii)
        if any(r < 0 for r in rs):
            raise DecodeError("range", "negative obstacle radius")
        return Obstacles(cs, rs, dims)
    if kind == "stats":
        ages = _counts(obj.get("ages"), "ages", MAX_HIST_BINS)
        lat = _counts(obj.get("lat", {}), "lat", MAX_HIST_BINS)
        health = _health(obj.get("x", {}))
        heard = obj.get("h", [])
        if (not isinstance(heard, list) or len(heard) > MAX_HEARD
                or not all(isinstance(h, int) and not isinstance(h, bool) and 0 <= h <= MAX_ID for h in heard)):
            raise DecodeError("schema", "h must be a list of agent ids")
        heard_n = obj.get("hn", [])
        if (not isinstance(heard_n, list) or len(heard_n) not in (0, len(heard))
                or not all(isinstance(c, int) and not isinstance(c, bool) and c >= 0 for c in heard_n)):
            raise DecodeError("schema", "hn must be a list of pose counts, one per id of h")
        return Stats(_int(obj, "id", 0, MAX_ID), _int(obj, "sent"), _int(obj, "recv"),
                     {str(k): v for k, v in _counts(obj.get("rej"), "rej", 64).items()},
                     _int(obj, "late"), _int(obj, "ticks"),
                     _bins(ages), _bins(lat), bool(obj.get("f", False)),
                     health, tuple(heard),
                     _times(obj.get("dep", {}), "dep"), _times(obj.get("ret", {}), "ret"), tuple(heard_n),
                     None if obj.get("b") is None else _float(obj["b"], "b", 1e11))
    raise DecodeError("kind", f"unknown kind {kind!r}")
