"""``zswarm run --cluster ADDRESS|auto|local[:K]``: check the flags, reach the cluster, greet every node
(its zswarm version), plan the run against the cluster's cores and memory, and carry it out.

Everything that can be refused is refused here, in one line and before any agent starts.
"""

from __future__ import annotations

import argparse
import copy

from zswarm.cluster.hosts import NodeLink
from zswarm.cluster.launch import ClusterLaunch
from zswarm.cluster.ray_cluster import connect, local_cores, parse_cluster
from zswarm.errors import UsageError
from zswarm.launch.plan import available_cores, available_mib, plan_from_args
from zswarm.launch.supervisor import _say

#: What a cluster run does not take (yet), and why.
REFUSED = {
    "role": "--cluster runs every role itself: the world here, a router and agents on every node",
    "ids": "--cluster places every agent itself (--placement); --ids is for machines started by hand",
    "routers": "--cluster runs one router per node",
    "robots": "--robots over a cluster is not supported yet: run robots' agents on their machines by hand",
    "listen": "--cluster picks each node's router endpoint itself",
    "connect": "--cluster joins the routers itself; --connect names a router for machines started by hand",
    "tracks": "--tracks over a cluster is not supported yet (each node would write its agents' tracks on its own disk)",
}


def check_flags(args: argparse.Namespace) -> None:
    given = {"role": args.role != ["router", "world", "agents"], "ids": args.ids is not None,
             "routers": args.routers != 1, "robots": args.robots is not None,
             "listen": args.listen is not None, "connect": args.connect is not None, "tracks": args.tracks is not None}
    for flag, set_ in given.items():
        if set_:
            raise UsageError(REFUSED[flag])
    if args.secure is not None and not args.cluster.startswith("local"):
        from zswarm.net.security import is_secure_dir

        if is_secure_dir(args.secure):  # one zswarm makes (empty) is signed by the CA it makes
            from zswarm.net.certs import require_ca_key

            require_ca_key(args.secure)


def node_label(k: int, node: dict) -> str:
    return f"node{k}@{node['NodeManagerAddress']}"


def cluster_run(args: argparse.Namespace) -> int:
    import zswarm

    address = parse_cluster(args.cluster)
    check_flags(args)
    if address.startswith("local"):  # its cores and memory are this machine's: refused before a node starts
        plan_from_args(copy.copy(args), cores=local_cores(address, available_cores()), memory_mib=available_mib())
    cluster = connect(address, available_cores(), getattr(args, "cluster_insecure_ok", False))
    links: list[NodeLink] = []
    try:
        driver = cluster.driver_node()
        nodes = sorted(cluster.alive_nodes(), key=lambda n: (n["NodeID"] != driver, n["NodeID"]))
        links = [NodeLink(n, node_label(k, n), _say) for k, n in enumerate(nodes)]
        for link in links:
            try:
                info = link.hello()
            except Exception as exc:  # noqa: BLE001 (Ray wraps what failed on the node)
                text = str(exc)
                why = ("zswarm is not installed there" if "No module named" in text or "ModuleNotFound" in text
                       else text.strip().splitlines()[-1][:160])
                raise UsageError(f"{link.label}: {why}; install the same zswarm on every node "
                                 f"(pip install -e \".[cluster]\")") from None
            if info["version"] != zswarm.__version__:
                raise UsageError(f"{link.label} has zswarm {info['version']} and this machine {zswarm.__version__}: "
                                 "install the same version on every node")
        cores = sum(link.cpus for link in links)
        memory = sum(n.get("Resources", {}).get("memory", 0.0) for n in nodes) / 2**20
        if address.startswith("local"):  # its nodes share this machine's cores and memory
            cores = min(cores, available_cores())
            memory = min(memory, available_mib() or memory)
        plan = plan_from_args(args, cores=cores, memory_mib=memory or None)
        return ClusterLaunch(plan, cluster, links, args.placement).run()
    finally:
        for link in links:
            link.close()
        cluster.close()
