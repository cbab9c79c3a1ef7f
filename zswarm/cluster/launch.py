"""``zswarm run --cluster``: one run over the nodes of a Ray cluster, carried out by the one-machine
:class:`~zswarm.launch.supervisor.Launch` with its processes placed on nodes.

Each node runs a Zenoh router (the first node's, on the driver's machine, is joined by every other, as
``--routers K`` does on one machine) and its share of agents, through its
:class:`~zswarm.cluster.hosts.NodeLink`; the world runs here, on the driver's machine, and writes the
recording and the summary here. Supervision, chaos and the ending are :class:`Launch`'s own: a node
is a host (:mod:`zswarm.host.local`), and an agent on another machine a handle with ``Popen``'s
interface.
"""

from __future__ import annotations

import time

import numpy as np

from zswarm.args import counted
from zswarm.cluster.hosts import NodeLink
from zswarm.cluster.pki import NodeIdentities
from zswarm.cluster.ray_cluster import RayCluster
from zswarm.errors import UsageError
from zswarm.launch.configs import agent_config_args
from zswarm.launch.local_runs import announce
from zswarm.launch.placement import place
from zswarm.args import id_ranges
from zswarm.launch.plan import Plan
from zswarm.launch.supervisor import Launch, _say
from zswarm.net.security import agent_config, router_configs, router_name
from zswarm.ports import LOOPBACK


class ClusterLaunch(Launch):
    def __init__(self, plan: Plan, cluster: RayCluster, links: list[NodeLink], placement: str) -> None:
        super().__init__(plan)
        self.cluster, self.links, self.placement = cluster, links, placement
        spawns = plan.spec.scenario.initial_positions(np.random.default_rng(plan.spec.seed))[list(plan.ids)]
        where = place(spawns, [link.cpus for link in links], placement)
        self.where = {i: k for i, k in zip(plan.ids, where)}  # Launch's one agent -> router map: a node's router
        self.placed = dict(self.where)  # where each agent started (a restarted one may run elsewhere)
        self.lost_seen: set[int] = set()  # nodes whose loss was taken in
        self.rejoin: list[tuple[float, list[int]]] = []  # (when, agents) of lost nodes, with --restart-after
        # --secure over other machines: each node's identities made there (a local cluster's nodes are
        # this machine: they use the --secure directory itself)
        self.node_keys = plan.secure is not None and not cluster.address.startswith("local")
        self.identities: NodeIdentities | None = None

    @property
    def ray_auth(self) -> str | None:
        return self.cluster.auth

    def run(self) -> int:
        try:
            return super().run()
        finally:
            for link in self.links:
                link.close()

    def _start_routers(self) -> None:
        """A router on every node, each joined to the first's (the driver's node: the world joins it)."""
        plan = self.plan
        extra = self.configs.get("router", [])
        self.endpoints = []
        # every node of a local cluster is this machine: its routers listen on loopback, the address a
        # --secure run's certificates name (Ray may know the nodes by the machine's own address)
        local = self.cluster.address.startswith("local")
        if self.node_keys:  # the secure directory is made (Launch.run): its CA signs them
            self.identities = NodeIdentities(plan.secure, routers=len(self.links))
        mine = router_configs(plan.secure, len(self.links)) if plan.secure is not None and local else None
        for k, link in enumerate(self.links):
            join = self.endpoints[0] if self.endpoints else None
            if self.identities is not None:  # each node's router its own identity, named in the access control
                self.identities.make(link, [router_name(k), *(self._identity(i) for i, n in self.where.items() if n == k)])
                extra = ["--config", self.identities.config(link, router_name(k))]
            elif mine is not None:
                extra = ["--config", str(mine[k])]
            try:
                self.endpoints.append(link.call("start_router", LOOPBACK if local else link.info["address"], join,
                                                extra, "tls" if plan.secure is not None else "tcp"))
            except Exception as exc:  # noqa: BLE001 (Ray wraps what the node raised)
                raise UsageError(f"node {link.label}: its router did not start ({str(exc).splitlines()[-1][:160]})") \
                    from None
            link.watch()
        self.endpoint = self.endpoints[0]
        self.announced = announce(self.spec.run, self.endpoint, self._monitor_config())  # zswarm monitor --run finds it
        if not plan.quiet:
            counts = np.bincount(list(self.where.values()), minlength=len(self.links))
            _say(", ".join(f"{link.label}: {c} agents, router {e}" for link, c, e in
                           zip(self.links, counts, self.endpoints)), err=False)

    def _started(self) -> str:
        return (f"run {self.spec.run!r}, {counted(len(self.plan.ids), 'agent')} on {counted(len(self.links), 'node')} "
                f"(placement {self.placement})")

    def _agent_config(self, agent: int) -> list[str]:
        """Under ``--secure`` over other machines, the identity made for it on its node."""
        if self.identities is None:
            return super()._agent_config(agent)
        link = self.links[self.where[agent]]
        return agent_config_args(self.plan, self.configs, agent, self.identities.config(link, self._identity(agent)))

    def _identity(self, agent: int) -> str:
        """The name agent ``agent`` holds its rights under: its own (``agent-I``) where the --secure
        directory's access control gives each agent its own, else the shared ``agent``."""
        return agent_config(self.plan.secure, agent).stem

    def _note_crashes(self) -> None:
        """A lost node's agents are crashed (said once, by its link); with ``--restart-after S`` they
        rejoin on the surviving nodes S seconds later, at their spawn positions."""
        for k, link in enumerate(self.links):
            if link.lost and k not in self.lost_seen:
                self.lost_seen.add(k)
                self.crashed |= {f"agent-{i}" for i in link.crashed}
                if link.crashed and self.plan.restart_after is not None:
                    self.rejoin.append((time.monotonic() + self.plan.restart_after, link.crashed))
        while self.rejoin and self.rejoin[0][0] <= time.monotonic() and self.world is not None and self.world.alive():
            _, agents = self.rejoin.pop(0)
            for i in agents:
                self._spawn_agent(i)
            _say(f"restarted agents {id_ranges(agents)} of a lost node on "
                 f"{', '.join(sorted({self.links[self.where[i]].label for i in agents}))}")
        super()._note_crashes()

    def _dead_routers(self) -> list[str]:
        """A node's router that died, as its node reports it (a lost node is not a dead router: its
        agents are crashed and the others carry on)."""
        return [f"{link.label}, exit {link.router_exit}" for link in self.links
                if link.router_exit is not None and not link.lost]

    def capacities(self) -> list[float]:
        return [0.0 if link.lost else float(link.cpus) for link in self.links]  # a lost node takes no one

    def host_of(self, agent: int) -> NodeLink | None:
        """Its node; one whose node was lost rejoins on the surviving node with the fewest agents (and
        that node's router: :meth:`router_of`)."""
        if self.links[self.where[agent]].lost:
            alive = [k for k, other in enumerate(self.links) if not other.lost]
            if not alive:
                return None
            load = {k: sum(1 for n in self.where.values() if n == k) for k in alive}
            self.where[agent] = min(alive, key=lambda k: load[k])
        return self.links[self.where[agent]]

    def _routing(self) -> dict:
        return {**super()._routing(),
                "cluster": {"address": self.cluster.address, "placement": self.placement,
                            "nodes": [{"label": link.label, **link.info, "router": e, "lost": link.lost}
                                      for link, e in zip(self.links, self.endpoints)],
                            "agent_node": {str(i): self.links[k].label for i, k in self.placed.items()},
                            "agent_node_at_end": {str(i): self.links[k].label for i, k in self.where.items()}}}
