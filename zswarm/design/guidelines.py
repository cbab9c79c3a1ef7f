"""The paper's analytical design guidelines (Propositions 1-5) as exact computations.

The 1-D collinear system (Figs 7-8): robot R, goal G, obstacle O on the x axis, R left of both and
moving right. With x = |psi^g|, y = |psi^o| and the multiplicative potential (eq 14), the force on R
along +x (eq 16) is

    F = -2 c_o y/l_o^2 e_o (1 - e_g) + 2 c_o x/l_g^2 e_o e_g + 2 c_g x/l_g^2 e_g,
    e_o = exp(-y^2/l_o^2), e_g = exp(-x^2/l_g^2),

so F >= 0  <=>  c_g/c_o >= B(x, y) = (l_g^2/x) e_o [ y/l_o^2 (e^{x^2/l_g^2} - 1) - x/l_g^2 ].

Prop 1 (Fig 7, R-G-O, y = x + d_m^go): the goal is reached from every start iff F > 0 on the whole
approach, i.e. c_g/c_o >= max_x B(x, x + d_m^go) (eqs 18-20; alpha is the bracket). The maximum is
exact for this 1-D system, not only sufficient.

Prop 2 (Fig 8, R-O-G, x = y + d_m^go): the robot stops at the outermost zero S of F (distance d_0^ro);
eq 22 asks F <= 0 at y = d_m^ro, i.e. c_g/c_o <= B(d_m^ro + d_m^go, d_m^ro). That is sufficient; the
exact condition for stopping at y >= d_m^ro is c_g/c_o <= sup_{y >= d_m^ro} B, reported as
``exact_upper_bound``.

Prop 3 (eq 34): epsilon = (N-1) e^{-1/2} (c_r/l_r + c_a/l_a) / (sqrt(2) c'_a N). The proof sums the
paper's pair forces over all N agents (eq 30), so it covers a swarm whose members all sense each
other (2 epsilon <= R) under the paper's interaction. Outside that it guarantees nothing and does not
bind: its verdict is shown, and the swarm check (which simulates the law in use) stands in.

Prop 4 (eqs 37-39), Prop 5 (eqs 40-41), the contact check, the swarm squeeze and the time step are in
:mod:`zswarm.design.swarm_checks`, each for our agents (sensing radius, interaction) beside the paper's
verdict.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from zswarm.design.bodies import body_check
from zswarm.design.swarm_checks import contact, prop4, prop5, swarm_rest
from zswarm.paper.stiffness import time_step
from zswarm.control.safety import guarantee
from zswarm.paper.formation import (
    epsilon,
    closed_form_spacing,
    equilibria,
    formation_offset,
    h_stable,
)
from zswarm.paper.neighbour_law import GATE_INNER
from zswarm.paper.numeric import maximize, sign_changes
from zswarm.paper.params import DesignMargins, Params, PotentialParams, groups_of

GRID = 40_001


def collinear_bound(x: np.ndarray, y: np.ndarray, p: PotentialParams) -> np.ndarray:
    """B(x, y): the c_g/c_o at which the collinear force of eq 16 vanishes (x = |psi^g|, y = |psi^o|).

    Written as (l_g^2/x)[ y/l_o^2 (e^{x^2/l_g^2 - y^2/l_o^2} - e^{-y^2/l_o^2}) - x/l_g^2 e^{-y^2/l_o^2} ]
    so that no exponential overflows.
    """
    with np.errstate(over="ignore", invalid="ignore"):
        e_o = np.exp(-np.square(y) / p.l_o**2)
        grow = np.exp(np.square(x) / p.l_g**2 - np.square(y) / p.l_o**2)
        return p.l_g**2 / x * (y / p.l_o**2 * (grow - e_o) - x / p.l_g**2 * e_o)


def alpha(x: np.ndarray, d_go: float, p: PotentialParams) -> np.ndarray:
    """alpha(|psi^g|) of eq 20: (x+d)/l_o^2 e^{x^2/l_g^2} - ((x+d)/l_o^2 + x/l_g^2)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return (x + d_go) / p.l_o**2 * np.expm1(np.square(x) / p.l_g**2) - x / p.l_g**2


def prop1_curve(x: np.ndarray, d_go: float, p: PotentialParams) -> np.ndarray:
    """Right side of eq 18 against x = |psi^g| (Fig 9's c_g/o curve)."""
    return collinear_bound(x, x + d_go, p)


def prop2_curve(y: np.ndarray, d_go: float, p: PotentialParams) -> np.ndarray:
    """Right side of eq 24 against y = |psi^o|."""
    return collinear_bound(y + d_go, y, p)


def _reach(p: PotentialParams, d_go: float) -> float:
    """How far along the axis the collinear curves can matter (beyond it they are ~0 or monotone)."""
    if p.l_g <= p.l_o:
        return d_go + 50.0 * p.l_o
    return d_go + 12.0 * p.l_o / math.sqrt(1.0 - (p.l_o / p.l_g) ** 2)


def _ratio(p: PotentialParams) -> float:
    return math.inf if p.c_o == 0 else p.c_g / p.c_o


def _goal_obstacle(params: Params) -> tuple[PotentialParams, DesignMargins]:
    """What Props 1-2 depend on (the goal and obstacle terms and the margins): their cache key."""
    p = params.potential
    return PotentialParams(l_o=p.l_o, l_g=p.l_g, c_o=p.c_o, c_g=p.c_g), params.margins


def prop1(params: Params) -> dict[str, Any]:
    return dict(_prop1(*_goal_obstacle(params)))


def prop2(params: Params) -> dict[str, Any]:
    return dict(_prop2(*_goal_obstacle(params)))


@lru_cache(maxsize=4096)
def _prop1(p: PotentialParams, margins: DesignMargins) -> dict[str, Any]:
    d = margins.d_m_go
    xs = np.linspace(0.0, _reach(p, d), GRID)[1:]
    x_max, bound, i = maximize(lambda x: prop1_curve(x, d, p), xs)
    if i == len(xs) - 1 and p.l_g <= p.l_o:
        bound = math.inf
    bound = max(bound, 0.0)
    roots = sign_changes(lambda x: alpha(x, d, p), xs)
    d_0 = roots[0][0] if roots else None
    ratio = _ratio(p)
    holds = ratio >= bound
    detail = (
        f"c_g/c_o = {ratio:.4g} {'>=' if holds else '<'} {bound:.4g}, the largest c_g/c_o the obstacle's "
        f"push requires (at |psi_g| = {x_max:.4g}) for a goal {d:g} from an obstacle"
        + ("" if holds else ": agents stall before such a goal")
    )
    return {"holds": holds, "lower_bound": bound, "d_0_go": d_0, "argmax": float(x_max),
            "margin": ratio - bound, "detail": detail}


def _outer_root(curve, level: float, ys: np.ndarray) -> float | None:
    roots = sign_changes(lambda y: curve(y) - level, ys)
    return roots[-1][0] if roots else None


@lru_cache(maxsize=4096)
def _prop2(p: PotentialParams, m: DesignMargins) -> dict[str, Any]:
    d, d_ro = m.d_m_go, m.d_m_ro
    curve = lambda y: prop2_curve(y, d, p)  # noqa: E731
    bound = float(curve(np.array(d_ro)))
    ys = np.linspace(d_ro, d_ro + _reach(p, d), GRID)
    _, exact, _ = maximize(curve, ys)
    ratio = _ratio(p)
    ys_all = np.linspace(0.0, d_ro + _reach(p, d), GRID)[1:]
    d_0 = _outer_root(curve, ratio, ys_all) if math.isfinite(ratio) else None
    holds = ratio <= bound
    detail = (
        f"c_g/c_o = {ratio:.4g} {'<=' if holds else '>'} {bound:.4g} (eq 22): "
        + (f"an agent heading at an obstacle stops {d_0:.4g} from it, outside d_m^ro = {d_ro:g}"
           if holds and d_0 is not None else
           f"the goal's pull can bring an agent closer than d_m^ro = {d_ro:g} to an obstacle")
    )
    return {"holds": holds, "upper_bound": bound, "exact_upper_bound": max(exact, bound),
            "d_0_ro": d_0, "d_0_ro_at_bound": _outer_root(curve, bound, ys_all),
            "margin": bound - ratio, "detail": detail}


def prop3(params: Params) -> dict[str, Any]:
    p, s = params.potential, params.swarm
    eps = epsilon(p, s.n_agents)
    holds = 2.0 * eps <= s.sensing_radius
    paper = params.interaction.spec.is_paper
    binding = holds and paper
    detail = (
        f"every agent ends within epsilon = {eps:.4g} of the swarm centre, a guarantee that assumes all "
        f"agents sense each other: 2 epsilon = {2 * eps:.4g} {'<=' if holds else '>'} "
        f"sensing_radius = {s.sensing_radius:g}"
        + ("" if holds else " (with this radius the swarm may split for good)")
        + ("" if paper else f"; proved for the paper's interaction, not {params.interaction.interaction}")
        + ("" if binding else ": it does not bind here; the swarm check judges this swarm")
    )
    return {"holds": holds, "binding": binding, "epsilon": eps, "margin": s.sensing_radius - 2.0 * eps,
            "detail": detail}


def formation(params: Params) -> dict[str, Any]:
    p = params.potential
    eq = equilibria(p)
    closed = closed_form_spacing(p)
    if eq.is_stable:
        why = f"pairs rest at d^f = {eq.spacing:.4g} (stable minimum of eq 26)"
    elif eq.attracts_at_contact:
        why = ("the pair potential has its minimum at distance 0: attraction beats repulsion at contact "
               "and close agents collapse onto each other")
    elif eq.disperses:
        why = "the pair potential keeps falling with distance: agents drift apart"
    else:
        why = "the pair potential has no stable spacing"
    if closed is not None and eq.spacing is not None:
        why += f"; eq 27's closed form, which ignores c'_a, gives {closed:.4g}"
    dims = params.swarm.dimensions
    hs = h_stable(p, dims)
    if not hs:
        why += (f"; not H-stable in {dims}-D (c_r l_r^{dims} = {p.c_r * p.l_r**dims:.3g} vs c_a l_a^{dims} = "
                f"{p.c_a * p.l_a**dims:.3g}, "
                f"l_r = {p.l_r:g} vs l_a = {p.l_a:g}): without the sensing radius, the more agents, the "
                f"tighter they would pack")
    return {"equilibrium_spacing": eq.spacing, "closed_form_spacing": closed,
            "stable": eq.is_stable, "h_stable": hs,
            "attracts_at_contact": eq.attracts_at_contact, "c_f": formation_offset(p),
            "unstable_spacings": list(eq.unstable), "detail": why}


@dataclass(frozen=True)
class DesignReport:
    params: Params
    prop1: dict[str, Any]
    prop2: dict[str, Any]
    prop3: dict[str, Any]
    prop4: dict[str, Any]
    prop5: dict[str, Any]
    formation: dict[str, Any]
    contact: dict[str, Any]
    swarm: dict[str, Any] | None  # None: not evaluated (the pair potential has no stable spacing)
    step: dict[str, Any] | None = None  # the time step check, when a dt was given
    body: dict[str, Any] | None = None  # the body check (zswarm.design.bodies)
    safety: dict[str, Any] | None = None  # what the safety filter guarantees (zswarm.control.safety.guarantee)

    def failures(self) -> list[str]:
        """The checks that fail and bind (Prop 3 binds only where it applies: see its docstring)."""
        out = [f"prop{i}" for i in (1, 2) if not getattr(self, f"prop{i}")["holds"]]
        out += [] if self.prop3["holds"] or not self.prop3.get("binding", True) else ["prop3"]
        out += [f"prop{i}" for i in (4, 5) if not getattr(self, f"prop{i}")["holds"]]
        out += [] if self.formation["stable"] else ["formation"]
        out += [] if self.contact["holds"] else ["contact"]
        out += [] if self.swarm is not None and self.swarm["holds"] else ["swarm"]
        out += [] if self.body is None or self.body["holds"] else ["body"]
        return out + ([] if self.step is None or self.step["holds"] else ["step"])

    def paper_failures(self) -> list[str]:
        """What the paper's own guidelines say (Props 1-5 as printed: every agent senses every other)."""
        checks = {f"prop{i}": getattr(self, f"prop{i}") for i in range(1, 6)}
        return [k for k, d in checks.items() if not d.get("paper_holds", d["holds"])]

    @property
    def ok(self) -> bool:
        return not self.failures()

    def to_json(self) -> dict[str, Any]:
        clean = lambda d: None if d is None else {k: _json_number(v) for k, v in d.items()}  # noqa: E731
        return {"params": self.params.flat(), **{f"prop{i}": clean(getattr(self, f"prop{i}"))
                for i in range(1, 6)}, "formation": clean(self.formation), "contact": clean(self.contact),
                "swarm": clean(self.swarm), "step": clean(self.step), "body": clean(self.body),
                "safety": clean(self.safety),
                "ok": self.ok, "failures": self.failures(), "paper_failures": self.paper_failures()}


def _json_number(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return None if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, list):
        return [_json_number(x) for x in v]
    return v


def check(params: Params, swarm: bool = True, dt: float | None = None) -> DesignReport:
    """Judge a parameter set against Propositions 1-5, the pair spacing and the swarm at rest, for the
    swarm it describes (its N, sensing radius and interaction); ``dt`` adds the time step check.

    ``swarm=False`` skips the (slower) swarm-at-rest simulation; the report then lists it as failed.
    """
    form = formation(params)
    stable = form["equilibrium_spacing"]
    spacing = stable or form["closed_form_spacing"]
    gate_in = GATE_INNER * params.interaction.gate * stable if stable else 0.0
    swarm = swarm_rest(params, stable) if swarm and form["stable"] else None
    return DesignReport(params, prop1(params), prop2(params), prop3(params), prop4(params, stable),
                        prop5(params, spacing, gate_in), form, contact(params, stable), swarm,
                        None if dt is None else time_step(params, dt), body_check(params, stable),
                        guarantee(params, dt))


def has_guidelines(law: str) -> bool:
    """Propositions 1-5 and the swarm checks are about this law (a property of the law:
    :attr:`zswarm.laws.contract.SwarmLaw.guidelines`; apf's alone among the built-ins)."""
    from zswarm.errors import UsageError
    from zswarm.laws.registry import resolve

    try:
        return bool(resolve(law)[0].guidelines)
    except UsageError:
        return False  # a law that does not load has none (a run of it is refused anyway)


def _guarantee(safety: str | None) -> str:
    """What keeps agents the guidelines do not cover apart, under the run's filter mode (None: not known)."""
    if safety == "off":
        return "with --safety off nothing keeps them apart (--safety barrier would)"
    return "the safety filter is the guarantee (--safety barrier)"


def coverage(params: Params, safety: str | None = None) -> tuple[Params | None, str | None]:
    """Which agents the guidelines judge, and a line that says what they cover: every agent (the set
    itself, no line); the agents of a mixed swarm whose law has them, among themselves (the set at
    their N); or none (None, the line). ``safety``: the run's filter mode, which the line names."""
    groups = groups_of(params.mix.groups)
    rest = params.swarm.n_agents - sum(count for count, _, _ in groups)
    laws = [(count, law, body or params.body.body) for count, law, body in groups]
    laws += [(rest, params.law.law, params.body.body)] if rest else []
    guided = [(count, law) for count, law, _ in laws if has_guidelines(law)]
    n = sum(count for count, _ in guided)
    if n == params.swarm.n_agents:
        return params, None
    others = ", ".join(f"{count} {law}/{body}" for count, law, body in laws if not has_guidelines(law))
    if not guided:
        who = f"law {params.law.law}" if len(laws) == 1 else f"laws {others}"
        return None, (f"{who}: there are no analytical guidelines for it (Propositions 1-5 and the swarm checks are "
                      f"the paper's law's, apf); {_guarantee(safety)}")
    names = ", ".join(sorted({law for _, law in guided}))
    return params.with_values({"n_agents": n, "groups": ""}), (
        f"the guidelines cover the {n} agents that run {names}, among themselves; the other agents ({others}) have "
        f"none; {_guarantee(safety)}")


def verdict(params: Params, dt: float | None = None, safety: str | None = None) -> dict[str, Any]:
    """What a run records of its own design (``"design"`` in its summary): the verdict for the set it
    runs (its N, sensing radius and interaction), the failing checks, and the paper's own verdict, with
    what they cover in a mixed swarm (``covers``); where the guidelines cover no agent, ``ok`` None and
    the line of :func:`coverage`."""
    guided, note = coverage(params, safety)
    if guided is None:
        return {"ok": None, "law": params.law.law, "note": note, "failures": [], "paper_failures": [],
                "interaction": None, "n_agents": params.swarm.n_agents}
    report = check(guided, dt=dt)
    return {"ok": report.ok, "failures": report.failures(), "paper_failures": report.paper_failures(),
            "interaction": params.interaction.interaction, "n_agents": guided.swarm.n_agents,
            **({"covers": note} if note else {})}


def judged(params: Params, dt: float | None, explain: str, required: bool,
           safety: str | None = None) -> tuple[dict[str, Any], str | None]:
    """A run's own check before it starts: its verdict, and the line to print (``note: ...`` for a law
    the guidelines do not cover, ``warning: ...`` for a failing set; None when it passes); with
    ``required`` (``--require-design``) either is a :class:`UsageError` instead."""
    from zswarm.errors import UsageError

    result = verdict(params, dt, safety)
    if result["ok"] is None:
        line = result["note"]
    elif not result["ok"]:
        line = warning_line(result, explain)
    elif "covers" in result:
        return result, "note: " + result["covers"]
    else:
        return result, None
    if required:
        raise UsageError(line + " (--require-design)")
    return result, ("note: " if result["ok"] is None else "warning: ") + line


def warning_line(verdict_: dict[str, Any], explain: str) -> str:
    """One line for a run whose set fails: which checks, and the command that explains them."""
    return (f"the design fails for this run ({', '.join(verdict_['failures'])} at N = {verdict_['n_agents']}, "
            f"interaction {verdict_['interaction']}): see {explain}")
