"""``--secure`` over a cluster of other machines: every node's identities made where they are used.

A node makes the key pairs of its router and of each agent that runs there (:meth:`NodeActor.identities
<zswarm.cluster.node.NodeActor.identities>`) and sends their public halves; the driver's CA (the
``--secure`` directory's) signs them for the node's address and sends the certificates back with the
run's access control (:meth:`NodeActor.install <zswarm.cluster.node.NodeActor.install>`). Nothing
secret crosses the network: private keys never leave their node, and the CA's key never leaves the
driver. An agent that moves to another node, or rejoins on one when its node is lost, gets an
identity there first.
"""

from __future__ import annotations

from pathlib import Path

from zswarm.cluster.hosts import NodeLink
from zswarm.errors import UsageError
from zswarm.net.certs import sign
from zswarm.net.security import router_acl, router_name, with_routers


class NodeIdentities:
    """The identities each node holds, made on demand (one round trip per batch)."""

    def __init__(self, secure: Path, routers: int = 1) -> None:
        self.secure = Path(secure)
        self.ca_pem = (self.secure / "ca.pem").read_text()
        # every node's router its own identity (router, router-1, ...), each named in the access control
        self.acl = with_routers(router_acl(self.secure), [router_name(k) for k in range(routers)])
        self.folders: dict[str, str] = {}  # node label -> its keys folder, there
        self.held: dict[str, set[str]] = {}  # node label -> the names it has certificates for

    def make(self, link: NodeLink, names: list[str]) -> None:
        """Identities for ``names`` on ``link``'s node (those it has are kept)."""
        names = [n for n in names if n not in self.held.get(link.label, set())]
        if not names:
            return
        try:
            public = link.call("identities", names)
        except Exception as exc:  # noqa: BLE001 (Ray wraps what the node raised)
            raise UsageError(f"node {link.label}: cannot make its keys ({str(exc).strip().splitlines()[-1][:160]}); "
                             "--secure needs zswarm[tls] on every node") from None
        certs = sign(self.secure, public, hosts=(link.info["address"], "localhost"))
        self.folders[link.label] = link.call("install", self.ca_pem, certs, self.acl)
        self.held.setdefault(link.label, set()).update(names)

    def config(self, link: NodeLink, name: str) -> str:
        """The Zenoh config of ``name`` on ``link``'s node (its path there)."""
        self.make(link, [name])
        return f"{self.folders[link.label]}/{name}.json5"
