"""TLS and access control for a swarm: the Zenoh configuration of each role. The router, where every
message passes, enforces the rules: mutual TLS against the swarm's CA, rights by the certificate's
common name, deny by default (the table of roles: docs/running.md, "Secure runs")."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Sequence

from zswarm.net.certs import ROLES, CertPaths, make_certs
from zswarm.net.keys import Keys
from zswarm.ports import LOOPBACK

ANY_RUN = Keys("*", 1.0)  # the key expressions of every run: zswarm/*/...
ANY_RUN_3D = Keys("*", 1.0, dims=3)  # and of every 3-D run (a pose key has one more cell segment)

OBSERVE = ["declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query"]
RECEIVE = ["put", "delete", "query", "reply", "declare_subscriber", "declare_queryable", "liveliness_token"]


AGENT_SEND = ["put", "declare_queryable", "reply", "liveliness_token"]


def router_name(k: int) -> str:
    """The certificate common name of a run's k-th router (a cluster's k-th node's): the first is ``router``."""
    return "router" if k == 0 else f"router-{k}"


def is_router(name: str) -> bool:
    return name == "router" or name.startswith("router-")


def with_routers(acl: dict, names: Sequence[str]) -> dict:
    """``acl`` with the routers it lets forward named exactly ``names``."""
    acl = json.loads(json.dumps(acl))
    for subject in acl["subjects"]:
        if subject["id"] == "routers":
            subject["cert_common_names"] = list(names)
    return acl


def agent_name(i: int) -> str:
    """The certificate common name of agent ``i`` when every agent has its own identity."""
    return f"agent-{i}"


def access_control(agents: int = 0) -> dict:
    """The router's ``access_control`` block (default deny; rights by certificate common name).

    ``agents == 0``: one ``agent`` identity for all agents, which may publish any agent's pose.
    ``agents == N``: identities ``agent-0`` .. ``agent-{N-1}``, each allowed only the keys that end in
    its own id (its pose in any cell, its stats, its liveliness token), so an agent cannot speak for
    another; the shared ``agent`` certificate then has no rights to send.
    """
    rules = [
        {"id": "observe", "permission": "allow", "messages": OBSERVE, "key_exprs": ["zswarm/**"]},
        {"id": "receive", "permission": "allow", "flows": ["egress"], "messages": RECEIVE,
         "key_exprs": ["zswarm/**"]},
        {"id": "world-send", "permission": "allow", "flows": ["ingress"],
         "messages": ["put", "declare_queryable", "reply"],
         "key_exprs": [ANY_RUN.prey, ANY_RUN.tick, ANY_RUN.control, ANY_RUN.obstacles, ANY_RUN.all_reports_taken,
                       ANY_RUN.positions]},
        {"id": "world-started", "permission": "allow", "flows": ["ingress"], "messages": ["liveliness_token"],
         "key_exprs": [ANY_RUN.world_started]},
    ]
    rules.append({"id": "router-forward", "permission": "allow", "flows": ["ingress", "egress"],
                  "messages": [*RECEIVE, "declare_liveliness_subscriber", "liveliness_query"],
                  "key_exprs": ["zswarm/**"]})
    subjects = [{"id": "world", "cert_common_names": ["world"]}, {"id": "routers", "cert_common_names": ["router"]}]
    policies = [{"rules": ["world-send", "world-started"], "subjects": ["world"]},
                {"rules": ["router-forward"], "subjects": ["routers"]}]
    if agents == 0:
        rules.append({"id": "agent-send", "permission": "allow", "flows": ["ingress"], "messages": AGENT_SEND,
                      "key_exprs": [ANY_RUN.all_poses, ANY_RUN.all_stats, ANY_RUN.all_alive, ANY_RUN.all_members,
                                    ANY_RUN.handoff("*")]})
        subjects.append({"id": "agents", "cert_common_names": ["agent"]})
        policies.append({"rules": ["agent-send"], "subjects": ["agents"]})
        readers = ["agents", "world"]
    else:
        readers = ["world"]
        for i in range(agents):
            name = agent_name(i)
            rules.append({"id": f"{name}-send", "permission": "allow", "flows": ["ingress"], "messages": AGENT_SEND,
                          "key_exprs": [ANY_RUN.any_cell_pose(i), ANY_RUN_3D.any_cell_pose(i), ANY_RUN.stats(i),
                                        ANY_RUN.alive(i), ANY_RUN.any_cell_member(i),
                                        ANY_RUN_3D.any_cell_member(i), ANY_RUN.handoff(i)]})
            subjects.append({"id": name, "cert_common_names": [name]})
            policies.append({"rules": [f"{name}-send"], "subjects": [name]})
            readers.append(name)
    policies.insert(0, {"rules": ["observe", "receive"], "subjects": readers})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects,
            "policies": policies}


def tls(paths: CertPaths, listen: bool) -> dict:
    """``transport/link/tls`` for one role: mutual TLS against the swarm's CA. The files are named
    relative to the config's own folder (:func:`zswarm.net.config.zenoh_config` reads them there), so
    that the folder works wherever it is moved or copied, with its own files."""
    block = {"root_ca_certificate": paths.ca.name, "enable_mtls": True, "connect_private_key": paths.key.name,
             "connect_certificate": paths.cert.name, "verify_name_on_connect": True}
    if listen:
        block.update(listen_private_key=paths.key.name, listen_certificate=paths.cert.name)
    return block


def role_config(paths: CertPaths, endpoint: str, agents: int = 0) -> dict:
    """A complete Zenoh configuration: the router listens on ``endpoint``, every other role connects."""
    router = is_router(paths.name)
    conf: dict = {"mode": "router" if router else "client",
                  "scouting": {"multicast": {"enabled": False}},
                  "transport": {"link": {"tls": tls(paths, listen=router)}}}
    if router:
        conf["listen"] = {"endpoints": [endpoint]}
        conf["access_control"] = access_control(agents)
    else:
        conf["connect"] = {"endpoints": [endpoint]}
    return conf


def write_secure_dir(directory: Path, endpoint: str = "tls/localhost:7447",
                     hosts: tuple[str, ...] = ("localhost", LOOPBACK), names: tuple[str, ...] = ROLES,
                     days: int = 30, agents: int = 0) -> dict[str, Path]:
    """Make the CA and certificates, and write ``NAME.json5`` (a full Zenoh config) for every name;
    with ``agents = N`` also ``agent-0`` .. ``agent-{N-1}``, each with rights to its own keys only.

    Pass each file with ``--config``; ``--connect``/``--listen`` still override its endpoint.
    """
    names = tuple(names) + tuple(agent_name(i) for i in range(agents))
    certs = make_certs(directory, names=names, hosts=hosts, days=days)
    out = {}
    for name, paths in certs.items():
        path = Path(directory) / f"{name}.json5"
        path.write_text(json.dumps(role_config(paths, endpoint, agents), indent=2) + "\n")
        out[name] = path
    return out


def install_identities(directory: Path, ca_pem: str, certs: dict[str, str], acl: dict) -> dict[str, Path]:
    """On the machine whose keys they are (:func:`zswarm.net.certs.make_keys` left them in
    ``directory``): write the CA, each signed certificate, and ``NAME.json5`` for each name; the
    router's with ``acl`` as its access control (the run's, so that every router of it enforces the
    same rules)."""
    directory = Path(directory)
    (directory / "ca.pem").write_text(ca_pem)
    out = {}
    for name, pem in certs.items():
        paths = CertPaths(directory, name)
        paths.cert.write_text(pem)
        conf = role_config(paths, "tls/localhost:7447")
        if is_router(name):
            conf["access_control"] = acl
        out[name] = directory / f"{name}.json5"
        out[name].write_text(json.dumps(conf, indent=2) + "\n")
    return out


def router_configs(directory: Path, count: int) -> list[Path]:
    """The configs of a run's ``count`` routers from a secure directory, each router its own identity
    (:func:`router_name`): those missing are made there, signed by its CA for the hosts its first
    router's certificate names; every one's access control lists exactly these routers."""
    from zswarm.errors import UsageError
    from zswarm.net.certs import cert_hosts, make_keys, sign

    directory = Path(directory)
    names = [router_name(k) for k in range(count)]
    if count == 1:
        return [directory / "router.json5"]
    missing = [n for n in names if not (directory / f"{n}.json5").is_file()]
    if missing and not (directory / "ca.key").is_file():
        raise UsageError(f"--secure {directory} has no {missing[0]}.json5, and no ca.key to make it: each router of "
                         f"--routers {count} has its own identity (router, router-1, ...); give a directory zswarm made")
    if missing:
        certs = sign(directory, make_keys(directory, missing), hosts=cert_hosts(directory / "router.pem"))
        for name, pem in certs.items():
            CertPaths(directory, name).cert.write_text(pem)
    base = json.loads((directory / "router.json5").read_text())  # the first router's, as made or edited
    out = []
    for name in names:
        conf = json.loads(json.dumps(base))
        conf["transport"]["link"]["tls"].update(tls(CertPaths(directory, name), listen=True))
        if "access_control" in base:
            conf["access_control"] = with_routers(base["access_control"], names)
        path = directory / f"{name}.json5"
        path.write_text(json.dumps(conf, indent=2) + "\n")
        out.append(path)
    return out


def router_acl(directory: Path) -> dict:
    """The access control of a secure directory's router (what every router of a run enforces)."""
    return json.loads((Path(directory) / "router.json5").read_text())["access_control"]


def agent_config(directory: Path, agent: int) -> Path:
    """The config agent ``agent`` uses from a secure directory: its own identity if there is one."""
    own = Path(directory) / f"{agent_name(agent)}.json5"
    return own if own.is_file() else Path(directory) / "agent.json5"


def is_secure_dir(directory: Path) -> bool:
    return all((Path(directory) / f"{name}.json5").is_file() for name in ROLES)


def meshes(directory: Path) -> bool:
    """Whether the directory's router lets the other routers of a mesh forward (made by this version)."""
    try:
        control = json.loads((Path(directory) / "router.json5").read_text()).get("access_control", {})
    except (OSError, ValueError):
        return False
    return any(rule.get("id") == "router-forward" for rule in control.get("rules", []))
