"""Which interaction an agent uses with its neighbours: the paper's eqs 26-28, or a variant that scales.

The paper sums the pair force of eq 28 over every sensed neighbour. That sum grows with the number of
neighbours, so a dense swarm squeezes itself (docs/scaling.md). The variants change one thing each and
can be combined with ``+`` (``mean+gate``):

- ``mean``: cohesion as a neighbour mean (Reynolds 1987). The attraction terms of eq 28 (c_a and c'_a)
  are averaged over the sensed neighbours; the repulsion (c_r) is still summed, so crowding still
  pushes back. An agent's pull toward its neighbours is then bounded whatever their number.
- ``cutoff``: a smooth cut-off at the sensing radius R (Olfati-Saber 2006's bump). Each pair force is
  multiplied by rho(r/R), 1 up to 0.8 R and a half cosine to 0 at R, so a neighbour crossing R no
  longer makes the force jump by 2 c'_a R.
- ``gate``: a gated goal. An agent with a neighbour close ahead on the goal side adds no goal pull, so
  the goal's pull cannot pile up along a chain of agents (the crowding gate; ``gate`` sets how close,
  as a fraction of the pair spacing d^f).
- ``nearest``: a topological cap: only the ``k_nearest`` nearest sensed neighbours count (SwarmLab's
  max_neig, Ballerini et al. 2008).
- ``swirl``: a circulation about the goal. Within ``swirl_radius`` of the goal an agent adds ``swirl``
  times its goal pull turned a quarter turn (about the vertical in 3-D), whatever the gate says: the
  part of a gathered swarm near the goal turns about it, making room for the agents the gate holds
  back, so a swarm too wide to press onto the goal still centres on it (docs/scaling.md).

``paper`` is none of them. ``scalable`` names the combination chosen by measurement (docs/scaling.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from zswarm.errors import ParamError

MODIFIERS: tuple[str, ...] = ("mean", "cutoff", "gate", "nearest", "swirl")
#: The combination the measurements of docs/scaling.md chose for large swarms.
SCALABLE: tuple[str, ...] = ("mean", "gate")
NAMES: tuple[str, ...] = ("paper", *MODIFIERS, "scalable")


@dataclass(frozen=True)
class Interaction:
    """The modifiers of eqs 26-28 in use (all False: the paper's interaction)."""

    mean: bool = False
    cutoff: bool = False
    gate: bool = False
    nearest: bool = False
    swirl: bool = False

    @cached_property
    def name(self) -> str:
        """Canonical name: ``paper``, or the modifiers in a fixed order joined by ``+``."""
        used = [m for m in MODIFIERS if getattr(self, m)]
        return "+".join(used) if used else "paper"

    @cached_property
    def is_paper(self) -> bool:  # read by an agent's law every tick
        return not (self.mean or self.cutoff or self.gate or self.nearest or self.swirl)



def parse_interaction(text: str) -> Interaction:
    """``paper``, ``scalable``, or modifiers joined by ``+`` (``mean+gate``); raises :class:`ParamError`."""
    if not isinstance(text, str) or not text.strip():
        raise ParamError(f"interaction must be a name: {', '.join(NAMES)}, or modifiers joined by + "
                         f"(e.g. mean+gate) (got {text!r})")
    parts = [part.strip() for part in text.strip().split("+")]
    used: set[str] = set()
    for part in parts:
        if part == "scalable":
            used.update(SCALABLE)
        elif part in MODIFIERS:
            used.add(part)
        elif part == "paper" and len(parts) == 1:
            pass
        else:
            raise ParamError(f"unknown interaction {text!r}: use {', '.join(NAMES)}, or modifiers joined by + "
                             f"({', '.join(MODIFIERS)}; e.g. mean+gate)")
    return Interaction(**{m: True for m in used})
