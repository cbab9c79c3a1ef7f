"""The design checks as a figure a reader can measure on: ``zswarm design --figure design.png|svg``.

Four panels, every axis labelled, each bound marked with the exact value ``zswarm design --json``
reports:

- Fig 9 / Prop 1: the c_g/c_o the obstacle's push requires against |psi_g| (eq 18's right side,
  the goal d_m^go from the obstacle), its maximum (the bound), and alpha (eq 20) on its own axis;
- Prop 2: the c_g/c_o at which an agent heading at an obstacle stops, against |psi_o| (eq 24), with
  d_m^ro and the bound of eq 22 marked;
- the pair force of eq 28 against distance, with d^f, d_m^f = d^f/10 and 2 d^r marked;
- the verdicts as a table.

The chosen c_g/c_o is drawn across both bound panels, so a reader sees at once which side it falls on.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from zswarm.design.guidelines import DesignReport, alpha, prop1_curve, prop2_curve
from zswarm.paper.formation import pair_gain

FORMATS = (".png", ".svg", ".pdf")


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.4g}"
    return str(v)


def verdict_rows(report: DesignReport) -> list[tuple[str, str, str]]:
    """(check, verdict, bound) per check: what the table shows."""
    r = report
    prop3 = None if not r.prop3.get("binding", True) and not r.prop3["holds"] else r.prop3["holds"]
    rows = [
        ("Prop 1", r.prop1["holds"], f"c_g/c_o >= {_fmt(r.prop1['lower_bound'])}"),
        ("Prop 2", r.prop2["holds"], f"c_g/c_o <= {_fmt(r.prop2['upper_bound'])}"),
        ("Prop 3", prop3, f"2 eps = {_fmt(2 * r.prop3['epsilon'])} {'<=' if r.prop3['holds'] else '>'} "
                          f"R = {_fmt(r.params.swarm.sensing_radius)}"
                          + ("" if prop3 is not None else " (does not bind: local sensing)")),
        ("Prop 4", r.prop4["holds"], f"c_o/l_o = {_fmt(r.prop4['lhs'])} > {_fmt(r.prop4['rhs'])}"),
        ("Prop 5", r.prop5["holds"], f"c_r = {_fmt(r.prop5['lhs'])} > {_fmt(r.prop5['rhs'])}"),
        ("Formation", r.formation["stable"], f"d^f = {_fmt(r.formation['equilibrium_spacing'])}"),
        ("Contact", r.contact["holds"], f"{_fmt(r.contact['lhs'])} > {_fmt(r.contact['rhs'])}"),
        ("Swarm", bool(r.swarm and r.swarm["holds"]),
         f"closest pair {_fmt((r.swarm or {}).get('min_pair_distance'))}"),
    ]
    if r.step is not None:
        rows.append(("Time step", r.step["holds"], f"2 v_max dt = {_fmt(r.step['step'])}, k dt = {_fmt(r.step['k_dt'])}"))
    return [(name, "n/a" if ok is None else "holds" if ok else "FAILS", bound) for name, ok, bound in rows]


def draw(report: DesignReport):
    """The figure (a matplotlib Figure; the caller saves or renders it)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams["svg.fonttype"] = "none"  # text stays text in an SVG: searchable, editable
    p, m, s = report.params.potential, report.params.margins, report.params.swarm
    ratio = p.c_g / p.c_o if p.c_o else math.inf
    fig, axes = plt.subplots(2, 2, figsize=(13, 9), constrained_layout=True)
    (ax1, ax2), (ax3, ax4) = axes

    # Fig 9 / Prop 1
    x_peak = report.prop1["argmax"]
    x = np.linspace(1e-4, max(4.0 * x_peak, 3.0 * p.l_o, 0.5), 800)
    curve = prop1_curve(x, m.d_m_go, p)
    ax1.plot(x, curve, color="tab:orange", label="c_g/c_o the obstacle's push requires (eq 18)")
    bound = report.prop1["lower_bound"]
    ax1.plot([x_peak], [bound], "o", color="tab:red")
    ax1.annotate(f"bound {_fmt(bound)} at |psi_g| = {_fmt(x_peak)}", (x_peak, bound), textcoords="offset points",
                 xytext=(8, 8), color="tab:red")
    if math.isfinite(ratio):
        ax1.axhline(ratio, color="tab:green", linestyle="--", label=f"chosen c_g/c_o = {_fmt(ratio)}")
    ax1.set_xlabel("|psi_g|: distance to the goal")
    ax1.set_ylabel("c_g / c_o")
    ax1.set_ylim(bottom=min(0.0, float(np.nanmin(curve))))
    twin = ax1.twinx()
    twin.plot(x, alpha(x, m.d_m_go, p), color="tab:blue", alpha=0.5, linewidth=1, label="alpha (eq 20)")
    twin.set_ylabel("alpha (eq 20)", color="tab:blue")
    lines = ax1.get_legend_handles_labels()
    more = twin.get_legend_handles_labels()
    ax1.legend(lines[0] + more[0], lines[1] + more[1], fontsize=8, loc="upper right")
    ax1.set_title(f"Fig 9 / Prop 1: goal d_m^go = {_fmt(m.d_m_go)} from an obstacle "
                  f"({report.prop1['holds'] and 'holds' or 'FAILS'})")
    ax1.grid(alpha=0.3)

    # Prop 2
    y = np.linspace(1e-4, max(3.0 * m.d_m_ro, 4.0 * p.l_o), 800)
    ax2.plot(y, prop2_curve(y, m.d_m_go, p), color="tab:orange", label="c_g/c_o at which the agent stops (eq 24)")
    upper = report.prop2["upper_bound"]
    ax2.axvline(m.d_m_ro, color="tab:gray", linestyle=":", label=f"d_m^ro = {_fmt(m.d_m_ro)}")
    ax2.plot([m.d_m_ro], [upper], "o", color="tab:red")
    ax2.annotate(f"bound {_fmt(upper)} (eq 22)", (m.d_m_ro, upper), textcoords="offset points", xytext=(8, 8),
                 color="tab:red")
    if math.isfinite(ratio):
        ax2.axhline(ratio, color="tab:green", linestyle="--", label=f"chosen c_g/c_o = {_fmt(ratio)}")
    if report.prop2["d_0_ro"] is not None:
        ax2.axvline(report.prop2["d_0_ro"], color="tab:green", linewidth=0.8,
                    label=f"where it stops: d_0^ro = {_fmt(report.prop2['d_0_ro'])}")
    ax2.set_xlabel("|psi_o|: distance to the obstacle")
    ax2.set_ylabel("c_g / c_o")
    ax2.set_ylim(bottom=0.0, top=max(2.5 * upper, 1.5 * ratio if math.isfinite(ratio) else 0.0, 1e-3))
    ax2.legend(fontsize=8)
    ax2.set_title(f"Prop 2: an agent heading at an obstacle ({report.prop2['holds'] and 'holds' or 'FAILS'})")
    ax2.grid(alpha=0.3)

    # pair force (eq 28)
    spacing = report.formation["equilibrium_spacing"]
    r = np.linspace(0.0, max(3.0 * (spacing or 0.0), 2.0 * max(p.l_r, min(p.l_a, 5.0))), 800)
    ax3.plot(r, -pair_gain(r * r, p) * r, color="tab:purple", label="-g(r) r: force on i along psi (eq 28)")
    ax3.axhline(0.0, color="black", linewidth=0.8)
    if spacing is not None:
        ax3.axvline(spacing, color="tab:green", linestyle="--", label=f"d^f = {_fmt(spacing)} (rest spacing)")
        ax3.axvline(spacing / 10.0, color="tab:orange", linestyle=":", label=f"d_m^f = d^f/10 = {_fmt(spacing / 10)}")
    ax3.axvline(2.0 * s.robot_radius, color="tab:red", linestyle=":", label=f"2 d^r = {_fmt(2 * s.robot_radius)} (contact)")
    if s.sensing_radius < r[-1]:
        ax3.axvline(s.sensing_radius, color="gray", linestyle="-.",
                    label=f"R = {_fmt(s.sensing_radius)} (sensing radius: no force beyond)")
    ax3.set_xlabel("r = |psi_f|: distance between two agents")
    ax3.set_ylabel("force (positive: repulsive)")
    ax3.legend(fontsize=8)
    ax3.set_title("the pair force of eqs 26-28")
    ax3.grid(alpha=0.3)

    # verdicts
    ax4.axis("off")
    rows = verdict_rows(report)
    table = ax4.table(cellText=[list(row) for row in rows], colLabels=["check", "verdict", "bound"],
                      loc="upper center", cellLoc="left", colWidths=[0.18, 0.14, 0.68])
    table.auto_set_font_size(False)
    table.set_fontsize(10)
    table.scale(1.0, 1.6)
    for i, (_, verdict, _) in enumerate(rows, start=1):
        table[i, 1].set_text_props(color={"holds": "tab:green", "n/a": "gray"}.get(verdict, "tab:red"), weight="bold")
    flat = report.params.flat()
    ax4.text(0.0, 0.02, "  ".join(f"{k}={_fmt(v)}" for k, v in flat.items()), fontsize=7, wrap=True,
             transform=ax4.transAxes)
    ax4.set_title("all guidelines hold" if report.ok else "guidelines fail: " + ", ".join(report.failures()))
    return fig


def save_figure(report: DesignReport, path: Path) -> None:
    """Write the figure; the format follows the suffix (.png, .svg or .pdf)."""
    import matplotlib.pyplot as plt

    fig = draw(report)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def render_png(report: DesignReport, dpi: int = 80) -> np.ndarray:
    """The figure as an RGB image array (for the Rerun recording)."""
    import matplotlib.pyplot as plt

    fig = draw(report)
    fig.set_dpi(dpi)
    fig.canvas.draw()
    image = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
    plt.close(fig)
    return image
