"""The ROS 2 wire over Zenoh, for the two routes by which a ROS 2 robot's topics reach plain Zenoh.

- ``rmw_zenoh`` (ROS 2's own Zenoh middleware, Tier 1 since Kilted): the key of a topic is
  ``<domain>/<name without its outer slashes>/<pkg>::msg::dds_::<Type>_/<type hash>``, the type hash
  ``RIHS01_`` + the REP-2016 type-description hash (Iron and later) or the literal
  ``TypeHashNotSupported`` (Humble). Every sample carries a 33-byte attachment (:class:`Attachment`);
  a ROS 2 subscriber drops a sample without it.
- ``ros2dds`` (zenoh-bridge-ros2dds): the key is the topic name without its leading slash, under the
  bridge's namespace if it has one; the payload is plain CDR with no attachment.

On both the payload is CDR with its 4-byte encapsulation header (``00 01 00 00``: little endian). The
message types, their CDR and their RIHS01 hashes come from ``rosbags`` (its type store of each
distro), not from code of ours. Anything that does not decode raises :class:`WireError` with a reason.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

from zswarm.errors import UsageError

ROUTES = ("rmw_zenoh", "ros2dds")
DISTROS = ("humble", "jazzy", "kilted", "rolling")
CDR_LE = b"\x00\x01\x00\x00"  # the encapsulation header zswarm writes: plain CDR, little endian
CDR_HEADERS = (CDR_LE, b"\x00\x00\x00\x00")  # what it reads: little or big endian
GID_SIZE = 16
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE
NO_TYPE_HASH = "TypeHashNotSupported"  # Humble's rmw_zenoh


class WireError(ValueError):
    """A ROS 2 sample that zswarm cannot take: ``reason`` is ``header``, ``cdr`` or ``attachment``."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason


@lru_cache(maxsize=None)
def typestore(distro: str) -> Any:
    """rosbags' type store of ``distro`` (rolling: its latest)."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise UsageError("talking to ROS 2 robots needs rosbags: pip install 'zswarm[ros]' (or rosbags)") from None

    stores = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY, "kilted": Stores.ROS2_KILTED,
              "rolling": Stores.LATEST}
    if distro not in stores:
        raise UsageError(f"distro must be one of {', '.join(DISTROS)} (got {distro!r})")
    return get_typestore(stores[distro])


def type_hash(distro: str, msgtype: str) -> str:
    """The type hash in an rmw_zenoh key: RIHS01_... (Iron and later), TypeHashNotSupported on Humble."""
    return NO_TYPE_HASH if distro == "humble" else typestore(distro).hash_rihs01(msgtype)


def dds_type_name(msgtype: str) -> str:
    """``geometry_msgs/msg/Twist`` -> ``geometry_msgs::msg::dds_::Twist_`` (rmw_zenoh's key segment)."""
    pkg, kind, name = msgtype.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


@dataclass(frozen=True)
class Route:
    """How one robot's topics reach Zenoh: ``route`` (rmw_zenoh or ros2dds), its ``distro``, the ROS
    domain and, through the bridge, the bridge's namespace."""

    route: str = "rmw_zenoh"
    distro: str = "jazzy"
    domain_id: int = 0
    bridge_namespace: str = ""

    def __post_init__(self) -> None:
        if self.route not in ROUTES:
            raise UsageError(f"route must be one of {', '.join(ROUTES)} (got {self.route!r})")
        if self.distro not in DISTROS:
            raise UsageError(f"distro must be one of {', '.join(DISTROS)} (got {self.distro!r})")
        if isinstance(self.domain_id, bool) or not isinstance(self.domain_id, int) or not 0 <= self.domain_id <= 232:
            raise UsageError(f"domain_id must be an integer in [0, 232] (got {self.domain_id!r})")

    @property
    def attached(self) -> bool:
        """Samples carry rmw_zenoh's attachment."""
        return self.route == "rmw_zenoh"

    def key(self, topic: str, msgtype: str) -> str:
        """The Zenoh key of ``topic`` (a ROS name such as ``/robot0/cmd_vel``) carrying ``msgtype``."""
        name = topic.strip("/")
        if self.route == "ros2dds":
            return f"{self.bridge_namespace.strip('/')}/{name}" if self.bridge_namespace.strip("/") else name
        return f"{self.domain_id}/{name}/{dds_type_name(msgtype)}/{type_hash(self.distro, msgtype)}"

    def encode(self, msgtype: str, message: Any) -> bytes:
        """``message`` (a rosbags message object of this distro) as CDR, header included."""
        return bytes(typestore(self.distro).serialize_cdr(message, msgtype))

    def decode(self, msgtype: str, payload: bytes) -> Any:
        """A CDR payload as a rosbags message object; :class:`WireError` for anything else."""
        if bytes(payload[:4]) not in CDR_HEADERS:
            raise WireError("header", f"not a CDR payload (header {bytes(payload[:4]).hex() or 'missing'})")
        try:
            return typestore(self.distro).deserialize_cdr(bytes(payload), msgtype)
        except Exception as exc:  # rosbags raises several kinds for a short or foreign payload
            raise WireError("cdr", f"not a {msgtype} ({type(exc).__name__})") from None

    def types(self) -> Any:
        """The message classes of this distro (``types['geometry_msgs/msg/Twist']``)."""
        return typestore(self.distro).types


@dataclass(frozen=True)
class Attachment:
    """rmw_zenoh's attachment of a published sample (33 bytes): the publisher's sequence number (from
    1), the source timestamp in nanoseconds, and the publisher's 16-byte GID, as Zenoh's own
    serializer writes them: two little-endian int64, then the GID's length (one LEB128 byte, 0x10) and
    its bytes. (Jazzy 0.2.0-0.2.3 and Humble 0.1.0-0.1.1 used an older, string-keyed form, which this
    does not write.)"""

    sequence: int
    stamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        if len(self.gid) != GID_SIZE:
            raise ValueError(f"a GID is {GID_SIZE} bytes (got {len(self.gid)})")
        return struct.pack("<qqB", self.sequence, self.stamp_ns, GID_SIZE) + bytes(self.gid)

    @classmethod
    def decode(cls, data: bytes | None) -> Attachment:
        if data is None:
            raise WireError("attachment", "the sample carries no attachment")
        data = bytes(data)
        if len(data) != ATTACHMENT_SIZE or data[16] != GID_SIZE:
            raise WireError("attachment", f"{len(data)} bytes, not rmw_zenoh's {ATTACHMENT_SIZE}")
        sequence, stamp = struct.unpack_from("<qq", data)
        return cls(sequence, stamp, data[17:])
