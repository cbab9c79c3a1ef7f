"""A law bound to a run: loaded, its parameters checked, its units fitted, and each call's answer
checked (a sequence of D finite floats). Every consumer (both simulators, the agent processes, robots,
the cluster) calls a law through :class:`BoundLaw`."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from zswarm.errors import Failure
from zswarm.laws.contract import Context, Observation, Observations, SwarmLaw


#: The exit status of an agent process whose law raised or answered with something other than a velocity.
EXIT_LAW_FAILED = 3


class LawError(RuntimeError):
    """A law's answer is not a velocity (wrong length, NaN, infinity, not numbers)."""


class FunctionLaw(SwarmLaw):
    """A plain function ``law(obs) -> velocity`` as a law without parameters, state or batched form."""

    fn: Callable[[Observation], Any]

    def command(self, obs: Observation) -> Any:
        return type(self).fn(obs)


def raised_at(exc: BaseException) -> str:
    """`` (file.py:LINE)``: where ``exc`` was raised, for a one-line message ("" without a traceback)."""
    import traceback
    from pathlib import Path

    frames = traceback.extract_tb(exc.__traceback__)
    return f" ({Path(frames[-1].filename).name}:{frames[-1].lineno})" if frames else ""


class LawFailed(Failure):
    """A law raised, or answered with something other than a velocity, while a run went on: one line."""

    @classmethod
    def of(cls, name: str, exc: BaseException, when: str) -> LawFailed:
        what = str(exc) if isinstance(exc, LawError) else f"law {name} raised {type(exc).__name__}: {exc}{raised_at(exc)}"
        return cls(f"{what} {when}".rstrip())


def function_law(fn: Callable[[Observation], Any], name: str) -> type[SwarmLaw]:
    """A :class:`SwarmLaw` class around ``fn``."""
    return type("FunctionLaw", (FunctionLaw,), {"fn": staticmethod(fn), "name": name,
                                                "reference": (fn.__doc__ or "").strip().split("\n")[0]})


def checked(out: Any, dims: int, name: str) -> np.ndarray | tuple[float, ...]:
    """``out`` as a velocity of ``dims`` finite floats (a tuple of floats stays one: a single form in
    plain floats is not turned into an array), or :class:`LawError` saying what it is."""
    if type(out) is tuple and len(out) == dims and all(isinstance(c, float) and math.isfinite(c) for c in out):
        return out
    try:
        v = np.asarray(out, dtype=float)
    except (TypeError, ValueError):
        raise LawError(f"law {name} returned {type(out).__name__} {out!r:.60}, not a sequence of {dims} numbers") from None
    if v.shape != (dims,):
        raise LawError(f"law {name} returned a velocity of shape {v.shape} in a {dims}-D run (want {dims} numbers)")
    if not np.all(np.isfinite(v)):
        raise LawError(f"law {name} returned a velocity that is not finite: {v.tolist()}")
    return v


@dataclass
class BoundLaw:
    """One run's law: the instance, where it came from and what it was set to."""

    law: SwarmLaw
    name: str
    source: str
    settings: dict[str, float | int]
    context: Context

    @property
    def state_size(self) -> int:
        return int(getattr(self.law, "state_size", 0))

    def start_state(self, lead: tuple[int, ...] = ()) -> np.ndarray:
        return np.zeros((*lead, self.state_size))

    def checked(self, out: Any, dims: int = 2) -> np.ndarray | tuple[float, ...]:
        """``out`` as a velocity of ``dims`` finite floats (:func:`checked`)."""
        return checked(out, dims, self.name)

    def decide(self, obs: Observation) -> tuple[np.ndarray | tuple[float, ...], np.ndarray]:
        """The single form: (velocity (D,), the agent's next state (S,))."""
        out = self.law.command(obs)
        if self.state_size:
            if not (isinstance(out, tuple) and len(out) == 2):
                raise LawError(f"law {self.name} keeps a state of {self.state_size}: return (velocity, state)")
            out, state = out
            state = np.asarray(state, dtype=float).reshape(self.state_size)
        else:
            state = obs.state
        return checked(out, obs.dims, self.name), state

    @property
    def has_batch(self) -> bool:
        return type(self.law).has_batch()

    def decide_batch(self, obs: Observations) -> tuple[np.ndarray, np.ndarray]:
        """The batched form where the law has one; otherwise the single form agent by agent (correct,
        and slower: a Python call per agent per step)."""
        if self.has_batch:
            out = self.law.batch(obs)
            if self.state_size:
                out, state = out
            else:
                state = obs.state
            v = np.asarray(out, dtype=float)
            if v.shape != obs.position.shape or not np.all(np.isfinite(v)):
                raise LawError(f"law {self.name}'s batched form returned shape {v.shape} (want "
                               f"{obs.position.shape}) or values that are not finite")
            return v, np.asarray(state, dtype=float)
        v, state = np.empty_like(obs.position), np.array(obs.state, dtype=float)
        for index in np.ndindex(*obs.lead):
            v[index], state[index] = self.decide(obs.one(index))
        return v, state

    def describe(self) -> dict[str, Any]:
        """What a run records of its law: name, source, parameters (published and in scenario units)."""
        law = self.law
        out: dict[str, Any] = {"name": self.name, "source": self.source, "reference": type(law).reference,
                               "settings": dict(self.settings)}
        params = law.describe_params()
        if params is not None:
            out["params"] = params
        units = getattr(law, "units", None)
        if units is not None:
            out["units"] = units.describe()
            out["scaled"] = {f.name: units.scaled(getattr(law.params, f.name), f.metadata.get("dimension", "none"))
                             for f in dataclasses.fields(law.params)}
        return out
