"""Forward-dynamics study, the figures: work-precision diagrams and stiff rods.
"""

from __future__ import annotations

import math

import numpy as np

from exo_bench.bench.stability.forward_evaluation import ForwardResults, StiffRun


# ----------------------------------------------------------------------------- plots
def work_precision_figure(panels: list[tuple[str, str, dict[str, list[tuple[float, float, float]]]]]):
    """One log-log panel per problem: x the error, y the run time, a line per integrator through
    its tolerances (each point labelled with its rtol exponent). ``panels``: (title, x label,
    {integrator: [(rtol, error, seconds), ...]})."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.2 * len(panels), 3.6), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    markers = {"RK45": "o", "DOP853": "s", "Radau": "^", "BDF": "v"}
    for ax, (title, xlabel, series) in zip(axes, panels):
        for integ, pts in series.items():
            pts = [p for p in pts if math.isfinite(p[1]) and p[1] > 0 and math.isfinite(p[2])]
            if not pts:
                continue
            r, e, s = map(np.array, zip(*sorted(pts)))
            ax.loglog(e, s, marker=markers.get(integ, "x"), label=integ, ms=4, lw=1)
            for ri, ei, si in zip(r, e, s):
                ax.annotate(f"{math.log10(ri):.0f}", (ei, si), fontsize=6, xytext=(2, 2), textcoords="offset points")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel("run time (s)", fontsize=8)
        ax.tick_params(which="both", labelsize=7)
        ax.grid(True, which="major", lw=0.3)
        ax.legend(fontsize=7)
    return fig


def stiff_figure(runs: list[StiffRun]):
    """Right-hand-side evaluations against the fastest rod rate, per integrator (log-log)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.0, 3.6), layout="constrained")
    ax = fig.subplots()
    by: dict[tuple[str, bool], list[StiffRun]] = {}
    for r in runs:
        by.setdefault((r.integrator, "masses x" in r.case), []).append(r)
    markers = {"RK45": "o", "DOP853": "s", "Radau": "^", "BDF": "v"}
    colors = {"RK45": "#1f77b4", "DOP853": "#ff7f0e", "Radau": "#2ca02c", "BDF": "#d62728"}
    for (integ, tiny), rs in by.items():
        rs = sorted(rs, key=lambda r: r.stiffness)
        x = [r.stiffness for r in rs]
        y = [r.sim.nfev for r in rs]
        if tiny:
            ax.scatter(x, y, marker=markers.get(integ, "x"), facecolors="none", edgecolors=colors.get(integ), s=40,
                       label=f"{integ}, tiny masses (k = 1e4)")
        else:
            ax.loglog(x, y, marker=markers.get(integ, "x"), color=colors.get(integ), label=f"{integ}, stiff k", ms=4,
                      lw=1)
        for r in rs:
            if not r.solved:
                ax.annotate("gave up", (r.stiffness, r.sim.nfev), fontsize=6, color="red")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("fastest rod rate sqrt(k / m) (1/s)", fontsize=8)
    ax.set_ylabel("right-hand-side evaluations", fontsize=8)
    ax.set_title("stiff rods: cost of one horizon", fontsize=9)
    ax.tick_params(which="both", labelsize=7)
    ax.grid(True, which="major", lw=0.3)
    ax.legend(fontsize=7)
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
              (f"energy drift: {e_first}", "max |E - E0| / max T", en_series)]
    if st_series:
        panels.append((f"stiff: {res.stiff_wp[0].case}", "|q(H) - q_ref(H)|", st_series))
    return {"stability-work-precision.png": work_precision_figure(panels),
            "stability-stiff.png": stiff_figure(res.stiff)}

