"""zswarm: decentralized swarms steered by artificial potential functions over Eclipse Zenoh.

Implements Kim, Wang & Shin (2006), "Decentralized Control of Autonomous Swarm Systems Using
Artificial Potential Functions: Analytical Design Guidelines".

The few things a notebook needs, imported on first use (``import zswarm`` itself loads nothing):

- ``zswarm.check(params)``: the design report of a parameter set (Propositions 1-5, formation,
  contact, the swarm squeeze); ``zswarm.DEFAULT_PARAMS``, ``zswarm.PAPER_PARAMS``, ``zswarm.Params``;
- ``zswarm.load_scenario(name_or_toml, law=None, law_params=None, **overrides)``: a scenario, e.g.
  ``load_scenario("moving-prey", n_agents=12, c_o=2.0)`` or ``load_scenario("moving-prey", law="boids",
  law_params={"w_sep": 2.0})`` (``law`` may be a function ``law(obs) -> velocity``, a
  ``zswarm.SwarmLaw`` class, or a name: ``zswarm.laws()`` lists them); ``zswarm.SCENARIOS`` names the
  registered ones;
- ``zswarm.simulate(scenario, seed, ...)``: the reference simulation; its result holds the summary,
  the per-step metrics and (``keep_trajectory=True``) the positions as arrays;
- ``zswarm.read_recording(path)``: a zswarm ``.rrd`` (and its segments) as its configuration, summary
  and per-step frames of ids, positions, velocities and the prey.

The command line (``zswarm --help``) and the processes (``python -m agents``, ``python -m world``)
are described in the README and ``docs/``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

if TYPE_CHECKING:
    from zswarm.swarm.scenarios import Scenario

_LAZY = {
    "check": ("zswarm.design.guidelines", "check"),
    "DesignReport": ("zswarm.design.guidelines", "DesignReport"),
    "Params": ("zswarm.paper.params", "Params"),
    "DEFAULT_PARAMS": ("zswarm.paper.params", "DEFAULT_PARAMS"),
    "PAPER_PARAMS": ("zswarm.paper.params", "PAPER_PARAMS"),
    "Scenario": ("zswarm.swarm.scenarios", "Scenario"),
    "SCENARIOS": ("zswarm.swarm.scenarios", "SCENARIOS"),
    "FaultModel": ("zswarm.swarm.faults", "FaultModel"),
    "SwarmObserver": ("zswarm.swarm.observer", "SwarmObserver"),
    "simulate": ("zswarm.sim.simulator", "simulate"),
    "Simulator": ("zswarm.sim.simulator", "Simulator"),
    "read_recording": ("zswarm.record.replay", "load_run"),
    "SwarmLaw": ("zswarm.laws.contract", "SwarmLaw"),
    "Observation": ("zswarm.laws.contract", "Observation"),
    "laws": ("zswarm.laws.registry", "known"),
}

__all__ = ["__version__", "load_scenario", *_LAZY]


def load_scenario(name: str, law: Any = None, law_params: dict[str, float] | None = None,
                  **overrides: Any) -> Scenario:
    """A registered scenario (``zswarm.SCENARIOS``) or a ``.toml`` file, with parameter overrides and
    the law its agents run: a name (``zswarm.laws()``), or a function or ``SwarmLaw`` class defined
    in the notebook (registered under ``module:name`` so every consumer finds it by name)."""
    from zswarm.swarm.scenarios import get_scenario

    if law is not None:
        overrides["law"] = law if isinstance(law, str) else f"{law.__module__}:{law.__qualname__}"
    overrides.update({f"law.{k}": v for k, v in (law_params or {}).items()})
    return get_scenario(name, overrides)


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        from importlib import import_module

        module, attr = _LAZY[name]
        return getattr(import_module(module), attr)
    raise AttributeError(f"module 'zswarm' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
