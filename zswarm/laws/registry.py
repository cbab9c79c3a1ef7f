"""Finding a law by name and binding it to a run, with every mistake refused in one line before any
process starts.

A name is a built-in (``apf``, ``olfati-saber``, ``vasarhelyi``, ``boids``), ``path/to/file.py:attr``,
``package.module:attr``, or a name an installed package registers under the entry-point group
``zswarm.laws``. The attribute is a function ``law(obs) -> velocity`` or a :class:`SwarmLaw` subclass.
:func:`bind` loads it, checks its parameters, fits it to the scenario and calls it once on a probe
observation made from the scenario (a wrong length, NaN, infinity or an exception is refused there).
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import inspect
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.errors import ParamError, UsageError
from zswarm.laws.bound import BoundLaw, LawError, function_law, raised_at
from zswarm.laws.contract import Context, Neighbour, Obstacle, Observation, Observations, SwarmLaw
from zswarm.paper.neighbours import obstacle_clearance

GROUP = "zswarm.laws"
BUILTIN: dict[str, str] = {
    "apf": "zswarm.laws.apf:Apf",
    "olfati-saber": "zswarm.laws.olfati_saber:OlfatiSaber",
    "vasarhelyi": "zswarm.laws.vasarhelyi:Vasarhelyi",
    "boids": "zswarm.laws.boids:Boids",
}


def _attr(module: Any, attr: str, where: str) -> Any:
    try:
        return getattr(module, attr)
    except AttributeError:
        names = sorted(n for n in vars(module) if not n.startswith("_") and callable(getattr(module, n)))
        raise UsageError(f"law {where}: {attr!r} is not defined there (it defines: {', '.join(names) or 'nothing'})") \
            from None


def _import_failed(where: str, exc: BaseException) -> UsageError:
    return UsageError(f"law {where} does not import: {type(exc).__name__}: {exc}{raised_at(exc)}")


@functools.lru_cache(maxsize=64)
def resolve(name: str) -> tuple[type[SwarmLaw], str]:
    """The law class ``name`` stands for, and where it came from (built-in, a file, a module, an entry
    point); raises :class:`UsageError` in one line."""
    if name in BUILTIN:
        module, _, attr = BUILTIN[name].partition(":")
        return getattr(importlib.import_module(module), attr), "built-in"
    target, sep, attr = name.rpartition(":")
    if sep and target.endswith(".py"):
        path = Path(target)
        if not path.is_file():
            raise UsageError(f"law {name}: no file {path} (give --law FILE.py:NAME with an existing file)")
        tag = hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:10]
        spec = importlib.util.spec_from_file_location(f"zswarm_user_law_{path.stem}_{tag}", path)
        module = importlib.util.module_from_spec(spec)
        try:
            spec.loader.exec_module(module)
        except BaseException as exc:  # noqa: BLE001 - a user's file may raise anything while it imports
            raise _import_failed(name, exc) from None
        return _as_law(_attr(module, attr, name), name), f"file {path}"
    looks_like_file = target if sep else name
    if (looks_like_file.endswith(".py") or "/" in looks_like_file
            or (Path(looks_like_file).suffix and Path(looks_like_file).is_file())):
        if not sep:
            raise UsageError(f"law {name}: name the law in the file too: --law {name}:NAME")
        raise UsageError(f"law {name}: a law file is Python source whose name ends in .py (got {target})")
    if sep and target and all(part.isidentifier() for part in target.split(".")):
        try:
            module = importlib.import_module(target)
        except BaseException as exc:  # noqa: BLE001
            raise _import_failed(name, exc) from None
        return _as_law(_attr(module, attr, name), name), f"module {target}"
    found = [ep for ep in _entry_points() if ep.name == name]
    if found:
        try:
            obj = found[0].load()
        except BaseException as exc:  # noqa: BLE001
            raise _import_failed(name, exc) from None
        return _as_law(obj, name), f"entry point {found[0].value}"
    raise UsageError(f"unknown law {name!r}: use one of {', '.join(known())}, FILE.py:NAME or package.module:NAME "
                     "(zswarm laws lists them)")


def known() -> list[str]:
    """Every law name this installation knows: the built-ins, then the entry points."""
    return [*BUILTIN, *sorted({ep.name for ep in _entry_points()} - set(BUILTIN))]


def _entry_points() -> Any:
    """The installed packages' laws, read only when a name is none of the built-ins (importlib.metadata
    costs an agent 30 ms and a megabyte it would load for nothing)."""
    from importlib.metadata import entry_points

    return entry_points(group=GROUP)


def _as_law(obj: Any, name: str) -> type[SwarmLaw]:
    if inspect.isclass(obj):
        if not issubclass(obj, SwarmLaw):
            raise UsageError(f"law {name}: a law class must subclass zswarm.laws.SwarmLaw (got {obj.__name__})")
        if not obj.name:
            obj.name = name
        return obj
    if not callable(obj):
        raise UsageError(f"law {name}: it names a value of type {type(obj).__name__}, not a function "
                         "law(obs) -> velocity or a SwarmLaw class")
    try:
        sig = inspect.signature(obj)
        sig.bind(None)
    except (TypeError, ValueError):
        raise UsageError(f"law {name}: a law function takes one argument, the observation: def law(obs) -> velocity "
                         f"(got {getattr(obj, '__name__', obj)}{_signature(obj)})") from None
    return function_law(obj, name)


def _signature(obj: Any) -> str:
    try:
        return str(inspect.signature(obj))
    except (TypeError, ValueError):
        return "(...)"


def context_of(scenario) -> Context:
    """What a law is told of the run (:class:`Context`)."""
    from zswarm.paper.formation import equilibria

    p = scenario.params
    spacing = equilibria(p.potential).spacing if scenario.formation else None
    return Context(dims=scenario.dimensions, dt=scenario.dt, v_max=p.swarm.v_max,
                   sensing_radius=p.swarm.sensing_radius, robot_radius=p.swarm.robot_radius,
                   spacing=spacing if spacing is not None else p.swarm.sensing_radius / 1.2)


def bind(scenario, combination: str | None = None, probe: bool = True, choice=None) -> BoundLaw:
    """The scenario's law (``choice``: another :class:`~zswarm.paper.params.LawChoice`, a group's of a
    mixed swarm), checked, fitted and probed; one-line :class:`UsageError` for every mistake."""
    choice = choice or scenario.params.law
    cls, source = resolve(choice.law)
    settings = dict(choice.settings)
    context = context_of(scenario)
    try:
        law = cls(cls.params_from(scenario, settings, combination), context)
    except ParamError as exc:
        raise UsageError(str(exc)) from None
    except Exception as exc:  # noqa: BLE001 - a user's constructor may raise anything
        raise UsageError(f"law {choice.law} could not be made: {type(exc).__name__}: {exc}") from None
    bound = BoundLaw(law, choice.law, source, settings, context)
    if probe:
        _probe(bound, scenario)
    return bound


def probe_observation(scenario, state_size: int) -> Observation:
    """One agent's observation made from the scenario: the first spawn point, its nearest spawned
    neighbours and obstacles within the sensing radius, the prey's start as the target."""
    p = scenario.params
    spawn = scenario.initial_positions(np.random.default_rng(0))
    me = spawn[0]
    radius = p.swarm.sensing_radius
    near = [q for q in spawn[1:] if np.linalg.norm(q - me) <= radius][:4]
    if not near:
        near = [me + np.eye(len(me))[0] * radius * 0.5]
    centres, radii = scenario.obstacle_arrays()
    gap = obstacle_clearance(me, centres, radii)
    obstacles = tuple(Obstacle(c.copy(), float(r)) for c, r, g in zip(centres, radii, gap) if g <= radius)
    return Observation(position=me.copy(), velocity=np.zeros_like(me),
                       neighbours=tuple(Neighbour(q.copy(), np.zeros_like(me), 0.1) for q in near),
                       obstacles=obstacles, target=np.asarray(scenario.prey_start, dtype=float),
                       v_max=p.swarm.v_max, dt=scenario.dt, state=np.zeros(state_size))


def _probe(bound: BoundLaw, scenario) -> None:
    """Call the law on :func:`probe_observation` (and its batched form on a batch of two): anything but
    D finite floats is refused in one line."""
    obs = probe_observation(scenario, bound.state_size)
    try:
        bound.decide(obs)
        if bound.has_batch:
            bound.decide_batch(Observations.stack([[obs, obs]]))
    except LawError as exc:
        raise UsageError(f"{exc} (on a probe observation from {scenario.name})") from None
    except Exception as exc:  # noqa: BLE001 - the user's code may raise anything
        raise UsageError(f"law {bound.name} raised {type(exc).__name__}: {exc}{raised_at(exc)} on a probe "
                         f"observation from {scenario.name}") from None


def describe(name: str) -> dict[str, Any]:
    """``zswarm laws``' entry for one law: source, reference, parameters with defaults, needs, forms."""
    import dataclasses

    cls, source = resolve(name)
    params = []
    if dataclasses.is_dataclass(cls.Params):
        for f in dataclasses.fields(cls.Params):
            params.append({"name": f.name, "default": f.default, "dimension": f.metadata.get("dimension", "none"),
                           "doc": f.metadata.get("doc", ""), "range": list(cls.ranges.get(f.name, ())) or None})
    state = cls.state_size if isinstance(cls.state_size, int) else None
    return {"name": name, "source": source, "reference": cls.reference, "needs": list(cls.needs),
            "batched": cls.has_batch(), "state": state, "tunable": bool(cls.ranges) or cls.guidelines,
            "guidelines": cls.guidelines,
            "params": params if not cls.guidelines else "the scenario's potential and interaction (zswarm design)"}
