"""What placement by space saves: the share of delivered poses that cross between routers.

An agent is handed every pose published into the cells its subscription disc meets
(:func:`zswarm.net.keys.in_reach`, the agents' own cell rule: disc R + 2 v_max dt, cells of side
R). A pose crosses between routers when its sender runs on another node than its receiver. This
computes that share over a whole run from the reference simulator's trajectory, for each placement,
with the nodes' capacities equal; a cluster run reports the same figure measured
(``cross_router_share`` in its summary). ``space_migrated``: placed by space at the start and moved
every ``migrate_every`` seconds of the run as ``zswarm run --migrate-every`` moves them
(:func:`zswarm.launch.placement.replace`, from where the agents are at that instant), with the moves
it took; ``space_replaced`` is what splitting the agents anew at each instant counted would give.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from zswarm.launch.placement import PLACEMENTS, place, replace
from zswarm.swarm.scenarios import get_scenario
from zswarm.net.keys import in_reach


def migrated(traj: np.ndarray, start: np.ndarray, nodes: int, every: float, dt: float) -> list[tuple[int, np.ndarray]]:
    """(first step, node of each agent) from each migration on: ``start`` at step 0, then the agents
    moved every ``every`` seconds from where they are then (:func:`replace`)."""
    out = [(0, start)]
    step = int(round(every / dt))
    for k in range(step, len(traj), step):
        out.append((k, np.asarray(replace(traj[k], out[-1][1], [1.0] * nodes))))
    return out


def placement_shares(scenario_name: str, n_agents: int, nodes: int, seed: int = 0, samples: int = 50,
                     duration: float | None = None, migrate_every: float = 10.0) -> dict[str, Any]:
    """The cross-router share of each placement over ``samples`` instants of the reference run."""
    from zswarm.net.runspec import RunSpec
    from zswarm.sim.simulator import simulate

    scenario = get_scenario(scenario_name, {"n_agents": n_agents})
    result = simulate(scenario, seed, keep_trajectory=True, metrics_every=10**9,
                      duration=duration if duration is not None else scenario.duration)
    traj = result.trajectory
    spec = RunSpec(run="placement", scenario_name=scenario_name, seed=seed, overrides=(("n_agents", n_agents),))
    r, cell = spec.subscription_radius, spec.keys.cell_size
    where = {how: np.asarray(place(traj[0], [1.0] * nodes, how)) for how in PLACEMENTS}
    epochs = migrated(traj, where["space"], nodes, migrate_every, scenario.dt)
    moves = sum(int((a != b).sum()) for (_, a), (_, b) in zip(epochs, epochs[1:]))
    crossed = {how: 0 for how in (*PLACEMENTS, "space-migrated", "space-replaced")}
    total = 0
    for k in np.linspace(0, len(traj) - 1, min(samples, len(traj))).round().astype(int):
        meets = in_reach(traj[k], r, cell)
        total += int(meets.sum())
        # what a placement that moved agents between nodes as the swarm moved could reach: the same
        # split of where the agents are now (zswarm places once, at the start)
        now = {**where, "space-migrated": [node for first, node in epochs if first <= k][-1],
               "space-replaced": np.asarray(place(traj[k], [1.0] * nodes, "space"))}
        for how, node in now.items():
            crossed[how] += int((meets & (node[:, None] != node[None, :])).sum())
    shares = {how.replace("-", "_"): (crossed[how] / total if total else None) for how in crossed}
    return {"scenario": scenario_name, "agents": n_agents, "nodes": nodes, "seed": seed, "samples": samples,
            "duration": float(result.summary.get("duration") or len(traj) * scenario.dt), **shares,
            "ratio": (shares["space"] / shares["round_robin"]) if shares["round_robin"] else None,
            "migrate_every": migrate_every, "moves": moves, "moves_per_agent": moves / n_agents,
            "ratio_migrated": (shares["space_migrated"] / shares["round_robin"]) if shares["round_robin"] else None}
