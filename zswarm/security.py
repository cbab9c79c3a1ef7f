"""TLS and access control for a swarm: the Zenoh configuration of each role.

The router is the only place every message passes, so it enforces the rules. Every session must
present a certificate signed by the swarm's CA (mutual TLS: no certificate, no connection), and the
router's access control gives rights by the certificate's common name:

========  ==========================================================================================
role      may send (router ingress)
========  ==========================================================================================
agent     poses ``zswarm/*/pose/**`` (put, queryable, reply), ``zswarm/*/stats/*``,
          liveliness ``zswarm/*/alive/*``
world     ``zswarm/*/prey``, ``zswarm/*/tick``, ``zswarm/*/control`` (put), and answers
          ``zswarm/*/obstacles`` (queryable, reply)
both      subscribe, query and watch liveliness anywhere under ``zswarm/**``, and receive from it
anyone    nothing: the default is deny, so a session with another name (``guest``) is connected
          but cannot publish, subscribe, query or answer
========  ==========================================================================================
"""

from __future__ import annotations

import json
from pathlib import Path

from zswarm.certs import ROLES, CertPaths, make_certs

OBSERVE = ["declare_subscriber", "query", "declare_liveliness_subscriber", "liveliness_query"]
RECEIVE = ["put", "delete", "query", "reply", "declare_subscriber", "declare_queryable", "liveliness_token"]


def access_control() -> dict:
    """The router's ``access_control`` block (default deny; rights by certificate common name)."""
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": [
            {"id": "observe", "permission": "allow", "messages": OBSERVE, "key_exprs": ["zswarm/**"]},
            {"id": "receive", "permission": "allow", "flows": ["egress"], "messages": RECEIVE,
             "key_exprs": ["zswarm/**"]},
            {"id": "agent-send", "permission": "allow", "flows": ["ingress"],
             "messages": ["put", "declare_queryable", "reply", "liveliness_token"],
             "key_exprs": ["zswarm/*/pose/**", "zswarm/*/stats/*", "zswarm/*/alive/*"]},
            {"id": "world-send", "permission": "allow", "flows": ["ingress"],
             "messages": ["put", "declare_queryable", "reply"],
             "key_exprs": ["zswarm/*/prey", "zswarm/*/tick", "zswarm/*/control", "zswarm/*/obstacles"]},
        ],
        "subjects": [{"id": "agents", "cert_common_names": ["agent"]},
                     {"id": "world", "cert_common_names": ["world"]}],
        "policies": [{"rules": ["observe", "receive"], "subjects": ["agents", "world"]},
                     {"rules": ["agent-send"], "subjects": ["agents"]},
                     {"rules": ["world-send"], "subjects": ["world"]}],
    }


def tls(paths: CertPaths, listen: bool) -> dict:
    """``transport/link/tls`` for one role: mutual TLS against the swarm's CA."""
    block = {"root_ca_certificate": str(paths.ca.resolve()), "enable_mtls": True,
             "connect_private_key": str(paths.key.resolve()), "connect_certificate": str(paths.cert.resolve()),
             "verify_name_on_connect": True}
    if listen:
        block.update(listen_private_key=str(paths.key.resolve()), listen_certificate=str(paths.cert.resolve()))
    return block


def role_config(paths: CertPaths, endpoint: str) -> dict:
    """A complete Zenoh configuration: the router listens on ``endpoint``, every other role connects."""
    router = paths.name == "router"
    conf: dict = {"mode": "router" if router else "client",
                  "scouting": {"multicast": {"enabled": False}},
                  "transport": {"link": {"tls": tls(paths, listen=router)}}}
    if router:
        conf["listen"] = {"endpoints": [endpoint]}
        conf["access_control"] = access_control()
    else:
        conf["connect"] = {"endpoints": [endpoint]}
    return conf


def write_secure_dir(directory: Path, endpoint: str = "tls/localhost:7447",
                     hosts: tuple[str, ...] = ("localhost", "127.0.0.1"), names: tuple[str, ...] = ROLES,
                     days: int = 30) -> dict[str, Path]:
    """Make the CA and certificates, and write ``NAME.json5`` (a full Zenoh config) for every name.

    Pass each file with ``--config``; ``--connect``/``--listen`` still override its endpoint.
    """
    certs = make_certs(directory, names=names, hosts=hosts, days=days)
    out = {}
    for name, paths in certs.items():
        path = Path(directory) / f"{name}.json5"
        path.write_text(json.dumps(role_config(paths, endpoint), indent=2) + "\n")
        out[name] = path
    return out


def is_secure_dir(directory: Path) -> bool:
    return all((Path(directory) / f"{name}.json5").is_file() for name in ROLES)
