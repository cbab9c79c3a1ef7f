"""The Zenoh configuration each process of a run is started with (``--config`` arguments, by role):
``--config`` / ``--router-config`` as given, or a ``--secure DIR``'s files, made there if it has none
(a CA, a certificate per agent and the configs: :mod:`zswarm.net.security`)."""

from __future__ import annotations

from typing import Callable

from zswarm.launch.plan import Plan


def role_configs(plan: Plan, n_agents: int, say: Callable[..., None]) -> dict[str, list[str]]:
    """``--config`` arguments for the router, the world and (without --secure) the agents, and the
    world's and agents' ``--connect-timeout``."""
    out = _role_configs(plan, n_agents, say)
    if plan.connect_timeout is not None:
        for role in ("world", "agent"):
            out[role] = [*out.get(role, []), "--connect-timeout", f"{plan.connect_timeout:g}"]
    return out


def _role_configs(plan: Plan, n_agents: int, say: Callable[..., None]) -> dict[str, list[str]]:
    if plan.secure is None:
        out = {}
        if plan.config is not None:
            out["world"] = out["agent"] = ["--config", str(plan.config)]
        if plan.router_config is not None:
            out["router"] = ["--config", str(plan.router_config)]
        return out
    from zswarm.net.security import router_configs, write_secure_dir

    if not any(plan.secure.iterdir()):  # a folder with files was checked (plan.check_secure_dir)
        write_secure_dir(plan.secure, agents=n_agents)
        if not plan.quiet:
            say(f"made a CA, certificates (one per agent) and configs in {plan.secure}", err=False)
    out = {"world": ["--config", str(plan.secure / "world.json5")]} if "world" in plan.roles else {}
    if "router" in plan.roles:  # each router of the mesh its own identity
        out["routers"] = [["--config", str(path)] for path in router_configs(plan.secure, plan.routers)]
    return out


def agent_config_args(plan: Plan, configs: dict[str, list[str]], agent: int, own: str | None = None) -> list[str]:
    """Agent ``agent``'s config: under --secure, its own identity's (``own``: the config made for it
    where it runs, :mod:`zswarm.cluster.pki`; else the directory's, if it has one); with
    --robots, the robots file (an agent it names drives that robot); with --tracks, the folder its
    track goes to."""
    extra = [] if plan.robots is None else ["--robots", str(plan.robots)]
    extra += [] if plan.tracks is None else ["--tracks", str(plan.tracks)]
    if plan.secure is None:
        return configs.get("agent", []) + extra
    from zswarm.net.security import agent_config

    timeout = [] if plan.connect_timeout is None else ["--connect-timeout", f"{plan.connect_timeout:g}"]
    return ["--config", own or str(agent_config(plan.secure, agent))] + timeout + extra
