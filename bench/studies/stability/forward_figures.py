"""Forward-dynamics study, the figures: work-precision diagrams and stiff rods.
"""

from __future__ import annotations

import math

import numpy as np

from exo_bench.bench.studies.stability.figures import FONT_MIN, legend_outside, style_axes
from exo_bench.bench.studies.stability.forward_evaluation import ForwardResults, StiffRun


#: One colour and marker per integrator, the same in every figure (no threshold is drawn here).
INTEGRATOR_STYLE = {"RK45": ("#1f77b4", "o"), "DOP853": ("#ff7f0e", "s"), "Radau": ("#2ca02c", "^"),
                    "BDF": ("#d62728", "v")}
#: What the numbers beside the work-precision points are (legend title and report caption).
RTOL_LABELS = "integrator (number beside each point: k, for rtol = 1e-k)"


def _style(integ: str) -> tuple[str, str]:
    return INTEGRATOR_STYLE.get(integ, ("#9467bd", "x"))


# ----------------------------------------------------------------------------- plots
def work_precision_figure(panels: list[tuple[str, str, dict[str, list[tuple[float, float, float]]]]]):
    """One log-log panel per problem: x the error, y the run time, a line per integrator through
    its tolerances (each point labelled with k of its rtol = 1e-k, explained in the legend's
    title). ``panels``: (title, x label with its unit, {integrator: [(rtol, error, seconds), ...]})."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.6 * len(panels) + 1.8, 4.2), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    for ax, (title, xlabel, series) in zip(axes, panels):
        for integ, pts in series.items():
            pts = [p for p in pts if math.isfinite(p[1]) and p[1] > 0 and math.isfinite(p[2])]
            if not pts:
                continue
            color, marker = _style(integ)
            r, e, s = map(np.array, zip(*sorted(pts)))
            ax.loglog(e, s, marker=marker, color=color, label=integ, ms=5, lw=1)
            for ri, ei, si in zip(r, e, s):
                ax.annotate(f"{-math.log10(ri):.0f}", (ei, si), fontsize=FONT_MIN, xytext=(3, 3),
                            textcoords="offset points")
        style_axes(ax, xlabel, "run time (s)", title)
    legend_outside(fig, title=RTOL_LABELS)
    return fig


def stiff_figure(runs: list[StiffRun]):
    """Right-hand-side evaluations against the fastest rod rate, per integrator (log-log)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.6, 4.4), layout="constrained")
    ax = fig.subplots()
    by: dict[tuple[str, bool], list[StiffRun]] = {}
    for r in runs:
        by.setdefault((r.integrator, "masses x" in r.case), []).append(r)
    gave_up = False
    for (integ, tiny), rs in by.items():
        rs = sorted(rs, key=lambda r: r.stiffness)
        x = [r.stiffness for r in rs]
        y = [r.sim.nfev for r in rs]
        color, marker = _style(integ)
        if tiny:
            ax.scatter(x, y, marker=marker, facecolors="none", edgecolors=color, s=50,
                       label=f"{integ}, tiny masses (k = 1e4)")
        else:
            ax.loglog(x, y, marker=marker, color=color, label=f"{integ}, stiff k", ms=5, lw=1)
        for r in rs:
            if not r.solved:
                gave_up = True
                ax.scatter([r.stiffness], [r.sim.nfev], marker="X", color="black", s=60, zorder=5)
    if gave_up:
        ax.scatter([], [], marker="X", color="black", s=60, label="gave up (evaluation budget)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    style_axes(ax, "fastest rod rate sqrt(k / m) (1/s)", "right-hand-side evaluations (count)",
               "stiff rods: cost of one horizon")
    legend_outside(fig, title="integrator")
    return fig


def forward_figures(res: ForwardResults) -> dict[str, object]:
    """``stability-work-precision.png`` and ``stability-stiff.png``."""
    first = next(iter(res.growth), None)
    rt_series: dict[str, list] = {}
    for rt in res.round_trips:
        if rt.case == first:
            rt_series.setdefault(rt.integrator, []).append((rt.rtol, rt.error, rt.sim.seconds))
    en_series: dict[str, list] = {}
    e_first = res.energy[0].case if res.energy else None
    for r in res.energy:
        if r.case == e_first:
            en_series.setdefault(r.integrator, []).append((r.rtol, r.drift / r.scale, r.sim.seconds))
    st_series: dict[str, list] = {}
    for r in res.stiff_wp:
        if r.solved:
            st_series.setdefault(r.integrator, []).append((r.rtol, r.error, r.sim.seconds))
    panels = [(f"round trip: {first}", "max |q - q*| (rad, m)", rt_series),
              (f"energy drift: {e_first}", "max |E - E0| / max T (dimensionless)", en_series)]
    if st_series:
        panels.append((f"stiff: {res.stiff_wp[0].case}", "max |q(H) - q_ref(H)| (rad, m)", st_series))
    return {"stability-work-precision.png": work_precision_figure(panels),
            "stability-stiff.png": stiff_figure(res.stiff)}

