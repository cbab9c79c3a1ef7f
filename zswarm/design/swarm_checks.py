"""The design checks that involve neighbours, for the swarm our agents are: sensing radius R, interaction.

The paper's Props 4 and 5 and the contact check reason as if every agent felt every other (c_p = N).
Our agents sum over the neighbours within R only, under an interaction (:mod:`zswarm.paper.interaction`)
that may average the cohesion, cap the count or gate the goal. Each check here returns the verdict
that counts for that swarm, with the paper's own verdict beside it (``paper_holds``, ``paper_detail``).

**How many neighbours can pull** (:func:`pulling_count`). Agents that keep at least d_min apart have
disjoint discs of radius d_min/2, all inside the disc of radius R + d_min/2 about the agent, so at
most (1 + 2R/d_min)^2 - 1 of them are within R (the packing bound; d_min = max(2 d^r, d^f/10), the
spacing Props 5 and the swarm check protect). With ``nearest`` at most k count; with ``mean`` the
pulls are averaged, so together they pull no harder than one.

**Prop 4 for our agents**: c_o/l_o > c_p(R) (c_a/l_a + c'_a r* e^{1/2} ... ) evaluated as eq 39 at
|psi_o| = l_o/sqrt2 and |psi_f| = r* = min(l_a/sqrt2, R) (a neighbour beyond R does not pull):

    sqrt2 e^{-1/2} c_o/l_o > c_p(R) f_a(r*),   f_a(r) = 2 c_a r/l_a^2 e^{-r^2/l_a^2} + 2 c'_a r,

with c_p(R) = min(N, 1 + count) (the paper's c_p = N is the case of R without bound).

**Prop 5 for our agents**: the paper's pair statement, f_r(d_m^f) > F^g(d^r) with
f_r(r) = 2 c_r r/l_r^2 e^{-r^2/l_r^2}. With the gate, P1 has P2 ahead within g_in whenever
d_m^f < g_in, so P1 takes no goal pull there and the load is 0. What R does not bound: the agents
behind P1 pass their own goal pull along the chain, so the load on a front pair grows with the depth
of the swarm (about sqrt N at constant density). Only the gate stops that; the swarm check measures it.

**Contact for our agents** (two touching agents, to first order in their gap): their repulsion
separates them at 2(2c_r/l_r^2) - 2(2c_a/l_a^2) (the pair's own attraction included); the quadratic
term of each other sensed agent closes them at 2c'_a, the goal's curvature at up to 2c_g/l_g^2:

    sum:      2c_r/l_r^2 - 2c_a/l_a^2 > c'_a (2 + m) + c_g/l_g^2,   m = min(N - 2, count - 1)
    mean:     2c_r/l_r^2 - 2c_a/l_a^2 > 2 c'_a + c_g/l_g^2  (the averaged cohesion closes the pair at
              most (2c_a/l_a^2 + 2c'_a)(1 + 1/K) <= 2(2c_a/l_a^2 + 2c'_a), whatever K)

(the paper's form, m = N - 2, is the first line with every agent sensed).

**Swarm** (brute force): N agents pressed against an obstacle by the goal (Fig 10) under the full law
with the interaction in use (:mod:`zswarm.design.squeeze`), up to :data:`SQUEEZE_MAX` agents. Beyond it
only a gated law is judged from that many (its load does not grow with N). An ungated law is judged up
to :data:`UNGATED_MAX` agents only: above it the squeeze against one obstacle is not enough, measured
(docs/scaling.md, docs/design.md): ``mean`` and ``mean+cutoff`` at N = 300 collide in every run of
``large-swarm`` while their squeeze keeps 0.165 and 0.228 apart, and the one false-safe set of an
earlier run of the guideline study was ungated at N = 300. The chains that carry the goal's pull form
in the passages a swarm crosses, a shape the single-obstacle squeeze does not have; so an ungated law
fails the check above that N.

**Time step** (:func:`time_step`): two agents closing at v_max each must not jump through the collision
distance in one step (2 v_max dt <= 2 d^r), and an agent must not bounce off an obstacle (the push's
slope k where it commands v_max: k dt <= 1), so a discrete-time effect is not mistaken for a guideline
failure.
"""

from __future__ import annotations

import math
from typing import Any

from zswarm.design.squeeze import squeeze
from zswarm.paper.params import Params

#: The swarm check simulates at most this many agents (about 6 s at 300 on one core).
SQUEEZE_MAX = 300
#: The largest N an ungated interaction (no ``gate``) passes the swarm check at: measured, see above.
UNGATED_MAX = 100


def min_spacing(params: Params, spacing: float | None) -> float:
    """d_min = max(2 d^r, d^f/10): the spacing the design protects."""
    return max(2.0 * params.swarm.robot_radius, spacing / 10.0 if spacing else 0.0)


def packing_bound(radius: float, d_min: float, dimensions: int = 2) -> int:
    """At most this many agents, pairwise at least ``d_min`` apart, lie within ``radius`` of a point
    other than the one there: (1 + 2R/d_min)^D - 1 (discs, or balls, of radius d_min/2 around each lie in
    the one of radius R + d_min/2, and do not overlap)."""
    return int(math.floor((1.0 + 2.0 * radius / d_min) ** dimensions)) - 1


def pulling_count(params: Params, spacing: float | None) -> tuple[int, str]:
    """How many neighbours' pulls add up on one agent, and why."""
    spec, n = params.interaction.spec, params.swarm.n_agents
    packed = packing_bound(params.swarm.sensing_radius, min_spacing(params, spacing), params.swarm.dimensions)
    if spec.mean:
        return 1, "the cohesion is a mean: all pull no harder than one"
    count = min(n - 1, packed)
    why = f"{count} = min(N - 1, {packed} that fit within R = {params.swarm.sensing_radius:g} at spacing " \
          f"{min_spacing(params, spacing):.3g})"
    if spec.nearest and params.interaction.k_nearest < count:
        count, why = params.interaction.k_nearest, f"{params.interaction.k_nearest} nearest"
    return max(count, 0), why


def _attraction(r: float, params: Params) -> float:
    p = params.potential
    return 2.0 * p.c_a * r / p.l_a**2 * math.exp(-r * r / p.l_a**2) + 2.0 * p.c_a_prime * r


def prop4(params: Params, spacing: float | None) -> dict[str, Any]:
    p, n = params.potential, params.swarm.n_agents
    c_p_paper = float(n)  # n_p = N - 1: c_p = n_p + 1 + (N - n_p - 1)/2 = N
    lhs = p.c_o / p.l_o
    paper_rhs = c_p_paper * (p.c_a / p.l_a + p.c_a_prime * p.l_a * math.exp(0.5))
    count, why = pulling_count(params, spacing)
    c_p = float(min(n, 1 + count)) if not params.interaction.spec.mean else 1.0
    r_star = min(p.l_a / math.sqrt(2.0), params.swarm.sensing_radius)
    # eq 39 at |psi_o| = l_o/sqrt2, scaled by sqrt2 e^{1/2} as eq 37 is
    rhs = c_p * _attraction(r_star, params) * math.sqrt(2.0) * math.exp(0.5) / 2.0
    holds, paper_holds = lhs > rhs, lhs > paper_rhs
    detail = (f"obstacle push c_o/l_o = {lhs:.4g} {'>' if holds else '<='} {rhs:.4g}, the pull of c_p = {c_p:g} "
              f"agents at {r_star:.3g} ({why})")
    paper_detail = (f"c_o/l_o = {lhs:.4g} {'>' if paper_holds else '<='} {paper_rhs:.4g}, the pull of {n - 1} "
                    f"agents lined up behind one (c_p = N = {n})")
    return {"holds": holds, "lhs": lhs, "rhs": rhs, "c_p": c_p, "r_star": r_star, "margin": lhs - rhs,
            "detail": detail, "paper_holds": paper_holds, "paper_rhs": paper_rhs, "paper_c_p": c_p_paper,
            "paper_detail": paper_detail}


def prop5(params: Params, spacing: float | None, gate_in: float) -> dict[str, Any]:
    p, d_r = params.potential, params.swarm.robot_radius
    if spacing is None:
        why = "no formation spacing d^f exists, so d_m^f = d^f/10 is undefined"
        return {"holds": False, "lhs": p.c_r, "rhs": None, "d_m_f": None, "margin": None, "detail": why,
                "paper_holds": False, "paper_detail": why}
    d_mf = spacing / 10.0
    rhs = (p.c_g * d_r * p.l_r**2 / (d_mf * p.l_g**2)
           * math.exp(-d_r**2 / p.l_g**2 + d_mf**2 / p.l_r**2))
    paper_holds = p.c_r > rhs
    paper_detail = (f"repulsion c_r = {p.c_r:.4g} {'>' if paper_holds else '<='} {rhs:.4g}, what the goal's "
                    f"pull needs at d_m^f = d^f/10 = {d_mf:.4g} for agents of radius {d_r:g}")
    gated = params.interaction.spec.gate and d_mf < gate_in
    if gated:
        detail = (f"the gate takes P1's goal pull away while P2 is within g_in = {gate_in:.3g} ahead "
                  f"(d_m^f = {d_mf:.4g}): no goal load on the pair; without it, " + paper_detail)
    else:
        detail = paper_detail + "; the goal pull of agents behind P1 adds up along chains (the swarm check)"
    return {"holds": gated or paper_holds, "lhs": p.c_r, "rhs": 0.0 if gated else rhs, "d_m_f": d_mf,
            "margin": p.c_r - (0.0 if gated else rhs), "detail": detail, "gated": gated,
            "paper_holds": paper_holds, "paper_rhs": rhs, "paper_detail": paper_detail}


def contact(params: Params, spacing: float | None) -> dict[str, Any]:
    p, n = params.potential, params.swarm.n_agents
    lhs = 2.0 * p.c_r / p.l_r**2 - 2.0 * p.c_a / p.l_a**2
    paper_rhs = p.c_a_prime * n + p.c_g / p.l_g**2
    if params.interaction.spec.mean:
        rhs = 2.0 * p.c_a_prime + p.c_g / p.l_g**2
        who = "the averaged cohesion (2 c'_a, whatever the count) and the goal"
    else:
        count, _ = pulling_count(params, spacing)
        others = max(min(n - 2, count - 1), 0)
        rhs = p.c_a_prime * (2 + others) + p.c_g / p.l_g**2
        who = f"the squeeze of {others} other sensed agents and the goal"
    holds, paper_holds = lhs > rhs, lhs > paper_rhs
    detail = (f"repulsion at contact 2c_r/l_r^2 - 2c_a/l_a^2 = {lhs:.4g} {'>' if holds else '<='} {rhs:.4g}, "
              f"{who}" + ("" if holds else ": agents pressed together merge"))
    paper_detail = (f"{lhs:.4g} {'>' if paper_holds else '<='} {paper_rhs:.4g} = c'_a N + c_g/l_g^2, every other "
                    f"agent sensed")
    return {"holds": holds, "lhs": lhs, "rhs": rhs, "margin": lhs - rhs, "detail": detail,
            "paper_holds": paper_holds, "paper_rhs": paper_rhs, "paper_detail": paper_detail}


def swarm_rest(params: Params, spacing: float | None) -> dict[str, Any]:
    """A swarm pressed against an obstacle by the goal (Fig 10), simulated with the law in use."""
    s, m, spec = params.swarm, params.margins, params.interaction.spec
    r = squeeze(params, min(s.n_agents, SQUEEZE_MAX))
    need = min_spacing(params, spacing)
    close_ok, obstacle_ok = r.min_pair_distance >= need, r.min_obstacle_distance >= m.d_m_ro
    beyond = s.n_agents > UNGATED_MAX and not spec.gate
    holds = close_ok and obstacle_ok and not beyond
    detail = (
        f"{r.n_agents} agents pressed against an obstacle by the goal (Fig 10) come {r.min_pair_distance:.3g} "
        f"from each other ({'>=' if close_ok else '<'} {need:.3g} = max(2 d^r, d^f/10)) "
        f"and {r.min_obstacle_distance:.3g} from the obstacle ({'>=' if obstacle_ok else '<'} d_m^ro = {m.d_m_ro:g})"
        + (f"; but {spec.name} does not stop the goal's pull adding up along chains, and above N = {UNGATED_MAX} "
           f"that crushes swarms in passages the squeeze does not model (add gate)" if beyond else "")
    )
    return {"holds": holds, "min_pair_distance": r.min_pair_distance, "required_pair_distance": need,
            "min_obstacle_distance": r.min_obstacle_distance, "n_simulated": r.n_agents,
            "final_median_nearest": r.final_median_nearest, "final_groups": r.final_groups,
            "margin": r.min_pair_distance - need, "detail": detail}


