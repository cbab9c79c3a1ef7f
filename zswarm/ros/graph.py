"""rmw_zenoh's liveliness tokens: what makes an agent's node, its publisher and its subscription show in
``ros2 node list`` and ``ros2 topic list`` (data flows without them; a ROS user expects to see them).

A token's key is (rmw_zenoh's ``liveliness_utils.cpp``)::

    @ros2_lv/<domain>/<zid>/<node id>/<entity id>/<NN|MP|MS>/<enclave>/<namespace>/<node name>
            [/<topic>/<type>/<type hash>/<qos>]

with every '/' inside a name replaced by '%' (the enclave and a root namespace are '/': '%'), the zid in
32 hex digits (rmw_zenoh's design document shows them padded: ``8b20917502ee955a...``; an older
rmw_zenoh printed each byte unpadded), and the QoS as ``reliability:durability:history,depth:
deadline:lifespan:liveliness`` where a field equal to rmw_zenoh's default profile is left empty (zswarm
declares ``::,10:,:,:,,``: keep the last 10, as ``ros2 run demo_nodes_cpp listener`` does). The tests
rebuild rmw_zenoh's documented examples (its docs/design.md) with these functions.
"""

from __future__ import annotations

from zswarm.ros.wire import Route, dds_type_name, type_hash

ADMIN_SPACE = "@ros2_lv"
QOS = "::,10:,:,:,,"  # reliable, volatile, keep last 10: the default profile, written as rmw_zenoh writes it


def mangle(name: str) -> str:
    return name.replace("/", "%")


def rmw_zid(zid_hex: str) -> str:
    """A Zenoh session id (hex, as zenoh prints it) as rmw_zenoh's documented tokens show it: 32 hex
    digits, most significant first."""
    return f"{int(zid_hex, 16):032x}"


def node_token(route: Route, zid: str, node_id: int, namespace: str, name: str) -> str:
    """The token of a node (NN): its id stands as both node and entity id."""
    return "/".join((ADMIN_SPACE, str(route.domain_id), rmw_zid(zid), str(node_id), str(node_id), "NN",
                     mangle("/"), mangle(namespace or "/"), mangle(name)))


def topic_token(route: Route, zid: str, node_id: int, entity_id: int, kind: str, namespace: str, name: str,
                topic: str, msgtype: str, qos: str = QOS) -> str:
    """The token of a publisher (``MP``) or a subscription (``MS``) of ``topic`` carrying ``msgtype``."""
    if kind not in ("MP", "MS"):
        raise ValueError(f"kind must be MP or MS (got {kind!r})")
    return "/".join((ADMIN_SPACE, str(route.domain_id), rmw_zid(zid), str(node_id), str(entity_id), kind,
                     mangle("/"), mangle(namespace or "/"), mangle(name), mangle(topic), dds_type_name(msgtype),
                     type_hash(route.distro, msgtype), qos))
