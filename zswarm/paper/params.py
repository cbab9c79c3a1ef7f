"""Parameter sets: frozen dataclasses, validated in one place.

Symbols follow Kim, Wang & Shin (2006):

- ``l_o, l_g, l_a, l_r``: correlation distances (ranges) of the obstacle, goal, inter-agent attraction
  and inter-agent repulsion Gaussians (eqs 7, 10, 26).
- ``c_o, c_g, c_a, c_r``: the matching strengths; ``c_a_prime`` is the auxiliary quadratic attraction
  c'_a of eq 26.
- ``d_m_go``: radius of the permissible goal region around an obstacle (Prop 1);
  ``d_m_ro``: the closest an agent may come to an obstacle (Prop 2).
- ``interaction``: how an agent uses its neighbours (:mod:`zswarm.paper.interaction`): ``paper``
  (eqs 26-28) or a variant that scales; ``gate``, ``k_nearest``, ``swirl`` and ``swirl_radius`` set
  the variants.
- ``body``: what a commanded velocity does (:mod:`zswarm.control.body`): ``point`` (the paper's),
  ``unicycle`` (``turn_rate``, ``lookahead``) or ``double-integrator`` (``accel``).
- ``law``: which control law the agents run (:mod:`zswarm.laws`): ``apf`` (the paper's, the default),
  another built-in, or a user's; ``law.NAME`` sets one of that law's own parameters (checked by the
  law when it is bound, :func:`zswarm.laws.registry.bind`).

Every field has one spec in :data:`FIELDS`; :func:`validate` is the only place that checks them, and
:meth:`Params.with_overrides` is how command lines (``--set NAME=VALUE``) reach them.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any, Mapping

from zswarm.errors import ParamError
from zswarm.paper.interaction import Interaction, parse_interaction


KINDS: tuple[str, ...] = ("point", "unicycle", "double-integrator")
#: Bodies whose pose carries a heading (on the wire, in the recording).
HEADED: frozenset[str] = frozenset({"unicycle"})


def parse_body(text: object) -> str:
    """A body's name, checked; raises :class:`ParamError`."""
    if not isinstance(text, str) or text.strip() not in KINDS:
        raise ParamError(f"body must be one of {', '.join(KINDS)} (got {text!r})")
    return text.strip()


@dataclass(frozen=True)
class FieldSpec:
    group: str
    kind: type
    lo: float
    lo_open: bool  # True: value must be > lo; False: >= lo
    doc: str
    hi: float = math.inf  # inclusive upper bound

    def describe(self) -> str:
        if self.kind is str:
            return "a name"
        kind = "an integer" if self.kind is int else "a finite number"
        bound = f"{kind} {'>' if self.lo_open else '>='} {self.lo:g}"
        return bound if math.isinf(self.hi) else f"{bound} and <= {self.hi:g}"


#: The most agents a scenario may hold: the reference simulator and the metrics work in O(N) memory
#: (cell grids, chunked brute force), and 100,000 agents already take minutes per simulated second.
MAX_AGENTS = 100_000


FIELDS: dict[str, FieldSpec] = {
    "l_o": FieldSpec("potential", float, 0.0, True, "obstacle correlation distance (eq 10)"),
    "l_g": FieldSpec("potential", float, 0.0, True, "goal correlation distance (eq 7)"),
    "l_a": FieldSpec("potential", float, 0.0, True, "inter-agent attraction range (eq 26)"),
    "l_r": FieldSpec("potential", float, 0.0, True, "inter-agent repulsion range (eq 26)"),
    "c_o": FieldSpec("potential", float, 0.0, False, "obstacle strength (eq 10)"),
    "c_g": FieldSpec("potential", float, 0.0, True, "goal strength (eq 7)"),
    "c_a": FieldSpec("potential", float, 0.0, False, "inter-agent attraction strength (eq 26)"),
    "c_r": FieldSpec("potential", float, 0.0, False, "inter-agent repulsion strength (eq 26)"),
    "c_a_prime": FieldSpec("potential", float, 0.0, False, "auxiliary quadratic attraction c'_a (eq 26)"),
    "n_agents": FieldSpec("swarm", int, 1, False, "number of agents N", hi=MAX_AGENTS),
    "v_max": FieldSpec("swarm", float, 0.0, True, "agent speed limit (velocity saturation)"),
    "sensing_radius": FieldSpec("swarm", float, 0.0, True, "range within which obstacles/agents are sensed"),
    "robot_radius": FieldSpec("swarm", float, 0.0, True, "physical radius d^r of an agent (Prop 5)"),
    "dimensions": FieldSpec("swarm", int, 2, False, "2 (the paper's plane) or 3", hi=3),
    "d_m_go": FieldSpec("margins", float, 0.0, False, "permissible goal-region radius d_m^go (Prop 1)"),
    "d_m_ro": FieldSpec("margins", float, 0.0, True, "minimum robot-obstacle distance d_m^ro (Prop 2)"),
    "interaction": FieldSpec("interaction", str, 0.0, False,
                             "paper (eqs 26-28), or modifiers joined by +: mean, cutoff, gate, nearest, swirl; "
                             "scalable = mean+gate"),
    "gate": FieldSpec("interaction", float, 0.0, True,
                      "gate: no goal pull with a neighbour ahead closer than gate x d^f", hi=10.0),
    "k_nearest": FieldSpec("interaction", int, 1, False, "nearest: how many nearest neighbours count"),
    "swirl": FieldSpec("interaction", float, 0.0, False,
                       "swirl: the circulation about the goal, as a multiple of the goal pull"),
    "swirl_radius": FieldSpec("interaction", float, 0.0, False,
                              "swirl: how far from the goal agents circulate (0: swirl cannot be used)"),
    "body": FieldSpec("body", str, 0.0, False, "what a command does: point (the paper's), unicycle, "
                      "double-integrator"),
    "turn_rate": FieldSpec("body", float, 0.0, True, "unicycle: the largest turn rate (rad/s)"),
    "lookahead": FieldSpec("body", float, 0.0, True,
                           "unicycle: how far ahead of the axle the tracked point is"),
    "accel": FieldSpec("body", float, 0.0, True, "double-integrator: the largest acceleration"),
    "law": FieldSpec("law", str, 0.0, False, "the control law: apf (the paper's), olfati-saber, vasarhelyi, "
                     "boids, FILE.py:NAME, package.module:NAME or an installed entry point (zswarm laws)"),
    "groups": FieldSpec("mix", str, 0.0, False, "a mixed swarm: COUNT:LAW[/BODY] joined by commas, e.g. "
                        "4:boids/unicycle (agents 0-3 run boids in unicycles; the rest run law in body)"),
}

#: ``law.NAME``: one of the law's own parameters (a finite number; the law checks its name and range).
LAW_PREFIX = "law."

#: How a name-valued field is read.
_NAMES = {"interaction": lambda v: parse_interaction(v).name, "body": parse_body, "law": lambda v: _law_name(v),
          "groups": lambda v: parse_groups(v)}


def _law_name(value: Any) -> str:
    if not isinstance(value, str) or not value.strip() or any(c.isspace() for c in value.strip()):
        raise ParamError(f"law must be a name (apf, olfati-saber, vasarhelyi, boids, FILE.py:NAME or "
                         f"package.module:NAME; zswarm laws lists them) (got {value!r})")
    return value.strip()


def parse_groups(value: Any) -> str:
    """``groups``, checked and written canonically: COUNT:LAW[/BODY] joined by commas ("" for none)."""
    if not isinstance(value, str):
        raise ParamError(f"groups must be COUNT:LAW[/BODY] joined by commas, e.g. 4:boids/unicycle (got {value!r})")
    return ",".join(f"{count}:{law}" + (f"/{body}" if body else "") for count, law, body in groups_of(value))


def groups_of(text: str) -> list[tuple[int, str, str | None]]:
    """The groups ``text`` lists, in order: (how many agents, the law, the body or None for the set's own).
    A law's name may hold ``:`` and ``/`` (FILE.py:NAME); a body is the part after the last ``/`` when
    that part is a body's name."""
    out = []
    for item in (part.strip() for part in text.split(",") if text.strip()):
        count, _, rest = item.partition(":")
        law, slash, body = rest.rpartition("/")
        if slash and body.strip() not in KINDS and re.fullmatch(r"[A-Za-z][\w-]*", body.strip()):
            raise ParamError(f"groups: {body.strip()!r} in {item!r} is not a body; the bodies are "
                             f"{', '.join(KINDS)} (COUNT:LAW[/BODY], e.g. 4:boids/unicycle)")
        if not slash or body.strip() not in KINDS:
            law, body = rest, ""
        try:
            n = int(count)
        except ValueError:
            n = 0
        if n < 1 or not law.strip():
            raise ParamError(f"groups: {item!r} is not COUNT:LAW[/BODY] with COUNT >= 1 (e.g. 4:boids/unicycle)")
        out.append((n, _law_name(law), parse_body(body) if body else None))
    return out


Value = float | int | str


def validate(name: str, value: Any) -> Value:
    """Check one field; return its value coerced to the field's type, or raise :class:`ParamError`."""
    if isinstance(name, str) and name.startswith(LAW_PREFIX):
        return _law_setting(name, value)
    spec = FIELDS.get(name)
    if spec is None:
        raise ParamError(f"unknown parameter {name!r}; known: {', '.join(FIELDS)}, or law.NAME for a parameter "
                         "of the law")
    if isinstance(value, bool):
        raise ParamError(f"{name} must be {spec.describe()} (got {value!r})")
    if spec.kind is str:
        return _NAMES[name](value)
    if spec.kind is int:
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if not isinstance(value, int):
            raise ParamError(f"{name} must be {spec.describe()} (got {value!r})")
    else:
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ParamError(f"{name} must be {spec.describe()} (got {value!r})")
        value = float(value)
    if value < spec.lo or (spec.lo_open and value == spec.lo) or value > spec.hi:
        raise ParamError(f"{name} must be {spec.describe()} (got {value!r})")
    return value


def _law_setting(name: str, value: Any) -> float | int:
    """``law.NAME = VALUE``: a finite number (its name and range are the law's to check)."""
    key = name[len(LAW_PREFIX):]
    if not key.isidentifier():
        raise ParamError(f"{name}: a law parameter is law.NAME with NAME a Python identifier (e.g. law.c1_alpha)")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ParamError(f"{name} must be a finite number (got {value!r})")
    return value


def _check(obj: Any) -> None:
    for f in dataclasses.fields(obj):
        object.__setattr__(obj, f.name, validate(f.name, getattr(obj, f.name)))


@dataclass(frozen=True)
class PotentialParams:
    """Strengths and ranges of the potentials (eqs 7, 10, 26). Defaults: see :data:`DEFAULT_PARAMS`."""

    l_o: float = 0.2
    l_g: float = 2.0
    l_a: float = 2.6
    l_r: float = 0.47
    c_o: float = 3.0
    c_g: float = 1.0
    c_a: float = 0.5
    c_r: float = 0.5
    c_a_prime: float = 0.1

    def __post_init__(self) -> None:
        _check(self)


@dataclass(frozen=True)
class SwarmParams:
    """The agents themselves: how many, how fast, how far they sense, how big they are, in how many
    dimensions they move."""

    n_agents: int = 10
    v_max: float = 1.0
    sensing_radius: float = 12.0
    robot_radius: float = 0.05
    dimensions: int = 2

    def __post_init__(self) -> None:
        _check(self)


@dataclass(frozen=True)
class DesignMargins:
    """The distances the design guidelines must guarantee (Props 1 and 2, Section 3.2.3)."""

    d_m_go: float = 0.2
    d_m_ro: float = 0.2

    def __post_init__(self) -> None:
        _check(self)


@dataclass(frozen=True)
class InteractionParams:
    """How an agent uses its neighbours: the interaction and the settings of its variants."""

    interaction: str = "paper"
    gate: float = 0.85
    k_nearest: int = 10
    swirl: float = 1.5
    swirl_radius: float = 0.0

    def __post_init__(self) -> None:
        _check(self)

    @property
    def spec(self) -> Interaction:
        return parse_interaction(self.interaction)


@dataclass(frozen=True)
class BodyParams:
    """What a commanded velocity does (:mod:`zswarm.control.body`): the body and its limits."""

    body: str = "point"
    turn_rate: float = 4.0
    lookahead: float = 0.25
    accel: float = 2.0

    def __post_init__(self) -> None:
        _check(self)


@dataclass(frozen=True)
class LawChoice:
    """Which control law the agents run and the values set for its own parameters (``law.NAME``);
    the law checks them when it is bound (:func:`zswarm.laws.registry.bind`)."""

    law: str = "apf"
    settings: tuple[tuple[str, float | int], ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "law", validate("law", self.law))
        object.__setattr__(self, "settings", tuple(sorted(
            (k, _law_setting(LAW_PREFIX + k, v)) for k, v in dict(self.settings).items())))

    def flat(self) -> dict[str, Value]:
        return {"law": self.law, **{LAW_PREFIX + k: v for k, v in self.settings}}


@dataclass(frozen=True)
class MixParams:
    """A mixed swarm (``groups``): groups of agents with their own law and body, listed in the order of
    their ids; the agents beyond them run the set's ``law`` in its ``body`` (:func:`groups_of`)."""

    groups: str = ""

    def __post_init__(self) -> None:
        _check(self)


@dataclass(frozen=True)
class Params:
    """A complete parameter set: potentials, swarm, design margins, interaction, body, the law and the
    groups of a mixed swarm."""

    potential: PotentialParams = field(default_factory=PotentialParams)
    swarm: SwarmParams = field(default_factory=SwarmParams)
    margins: DesignMargins = field(default_factory=DesignMargins)
    interaction: InteractionParams = field(default_factory=InteractionParams)
    body: BodyParams = field(default_factory=BodyParams)
    law: LawChoice = field(default_factory=LawChoice)
    mix: MixParams = field(default_factory=MixParams)

    def __post_init__(self) -> None:
        listed = sum(count for count, _, _ in groups_of(self.mix.groups))
        if listed > self.swarm.n_agents:
            raise ParamError(f"groups list {listed} agents, more than n_agents = {self.swarm.n_agents}")

    def flat(self) -> dict[str, Value]:
        """Every effective value by field name (the keys of :data:`FIELDS`, and ``law.NAME`` for each
        parameter set for the law)."""
        out: dict[str, Value] = {}
        for part in (self.potential, self.swarm, self.margins, self.interaction, self.body, self.mix):
            out.update(dataclasses.asdict(part))
        out.update(self.law.flat())
        return out

    def with_values(self, values: Mapping[str, Any]) -> Params:
        """A copy with some fields replaced (already-typed values; validated). Choosing another law
        drops the settings of the one before it."""
        groups: dict[str, dict[str, Any]] = {g: {} for g in ("potential", "swarm", "margins", "interaction", "body",
                                                             "mix")}
        law, settings = self.law.law, dict(self.law.settings)
        for name, value in values.items():
            if name.startswith(LAW_PREFIX):
                settings[name[len(LAW_PREFIX):]] = validate(name, value)
            elif name == "law":
                chosen = validate(name, value)
                if chosen != law:
                    law, settings = chosen, {k[len(LAW_PREFIX):]: v for k, v in values.items()
                                             if k.startswith(LAW_PREFIX)}
            else:
                groups[FIELDS[name].group if name in FIELDS else "potential"][name] = validate(name, value)
        return Params(
            potential=dataclasses.replace(self.potential, **groups["potential"]),
            swarm=dataclasses.replace(self.swarm, **groups["swarm"]),
            margins=dataclasses.replace(self.margins, **groups["margins"]),
            interaction=dataclasses.replace(self.interaction, **groups["interaction"]),
            body=dataclasses.replace(self.body, **groups["body"]),
            law=LawChoice(law, tuple(settings.items())),
            mix=dataclasses.replace(self.mix, **groups["mix"]),
        )

    def with_overrides(self, assignments: list[str]) -> Params:
        """Apply ``NAME=VALUE`` strings from a command line."""
        return self.with_values(parse_assignments(assignments))

    @classmethod
    def from_flat(cls, values: Mapping[str, Any]) -> Params:
        return cls().with_values(values)


def parse_assignments(assignments: list[str]) -> dict[str, Value]:
    """Parse ``NAME=VALUE`` strings (``VALUE`` may be a fraction such as ``1/3``, or a name)."""
    out: dict[str, Value] = {}
    for item in assignments:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ParamError(f"--set expects NAME=VALUE (got {item!r})")
        if name.startswith(LAW_PREFIX):
            out[name] = _law_setting(name, _parse_law_number(name, text.strip()))
            continue
        if name not in FIELDS:
            validate(name, 0)  # raises the unknown-name error
        out[name] = validate(name, _parse_number(name, text.strip()))
    return out


def _parse_law_number(name: str, text: str) -> float | int:
    try:
        if "/" in text:
            num, den = text.split("/", 1)
            return float(num) / float(den)
        try:
            return int(text)
        except ValueError:
            return float(text)
    except (ValueError, ZeroDivisionError):
        raise ParamError(f"{name} must be a finite number (got {text!r})") from None


def _parse_number(name: str, text: str) -> Value:
    if FIELDS[name].kind is str:
        return text
    try:
        if "/" in text:
            num, den = text.split("/", 1)
            return float(num) / float(den)
        if FIELDS[name].kind is int:
            try:
                return int(text)
            except ValueError:  # 1e5, 100.0: an integer written as a float
                value = float(text)
                if not value.is_integer():
                    raise
                return int(value)
        return float(text)
    except (ValueError, ZeroDivisionError):
        raise ParamError(f"{name} must be {FIELDS[name].describe()} (got {text!r})") from None


#: The paper's printed set (Sections 3.2.3, 4.2.2 and 5), with its swarm and margin values.
PAPER_POTENTIAL = PotentialParams(
    l_o=0.2, l_g=2.0, l_a=0.5, l_r=1.0, c_o=3.0, c_g=1.0, c_a=0.5, c_r=1.0 / 3.0, c_a_prime=0.1
)
PAPER_PARAMS = Params(potential=PAPER_POTENTIAL)

#: The shipped default: the paper's set with l_a = 2.6, l_r = 0.47 (the nearest passing set that
#: ``zswarm design --paper --nearest`` finds, rounded) and c_r = 1/2 for a margin (see README, "Defaults").
DEFAULT_PARAMS = Params()
