"""Forward-dynamics study, the figures: work-precision diagrams and stiff rods."""

from __future__ import annotations

import math

import numpy as np

from exo_bench.bench.studies.stability.figures import FONT_MIN, legend_outside, style_axes
from exo_bench.bench.studies.stability.forward_energy import StiffRun
from exo_bench.bench.studies.stability.forward_evaluation import ForwardResults


#: One colour and marker per integrator, the same in every figure (no threshold is drawn here).
INTEGRATOR_STYLE = {
    "RK45": ("#1f77b4", "o"),
    "DOP853": ("#ff7f0e", "s"),
    "Radau": ("#2ca02c", "^"),
    "BDF": ("#d62728", "v"),
}
#: What the numbers beside the work-precision points are (legend title and report caption).
RTOL_LABELS = (
    "integrator (number beside each point: k, for rtol = 1e-k;\nRadau and BDF: scipy's finite-difference "
    "Jacobian unless marked analytic)"
)


#: The suffix of a series run with the analytic Jacobian (same colour as its integrator, dotted, hollow).
ANALYTIC = ", analytic Jacobian"


def _style(integ: str) -> tuple[str, str]:
    return INTEGRATOR_STYLE.get(integ.removesuffix(ANALYTIC), ("#9467bd", "x"))


# ----------------------------------------------------------------------------- plots
def work_precision_figure(panels: list[tuple[str, str, dict[str, list[tuple]]]]):
    """One log-log panel per problem: x the error, y the run time, a line per integrator through
    its tolerances (each point labelled with k of its rtol = 1e-k, explained in the legend's
    title). ``panels``: (title, x label with its unit, {integrator: [(rtol, error, seconds[, RHS
    evaluations]), ...]}). Where points carry RHS evaluations, a second row plots them against the
    error. A series named ``<integrator>`` + :data:`ANALYTIC` is dotted with hollow markers (dashed
    lines are thresholds in every figure)."""
    from matplotlib.figure import Figure

    rows = 2 if any(len(p) > 3 for _, _, series in panels for pts in series.values() for p in pts) else 1
    fig = Figure(figsize=(4.6 * len(panels) + 1.8, 4.2 * rows), layout="constrained")
    axes = fig.subplots(rows, len(panels), squeeze=False)
    for col, (title, xlabel, series) in enumerate(panels):
        for row in range(rows):
            ax = axes[row, col]
            y_at, ylabel = (2, "run time (s)") if row == 0 else (3, "right-hand-side evaluations (count)")
            for integ, pts in series.items():
                pts = [p for p in pts if len(p) > y_at and math.isfinite(p[1]) and p[1] > 0 and math.isfinite(p[y_at])]
                if not pts:
                    continue
                color, marker = _style(integ)
                analytic = integ.endswith(ANALYTIC)
                r, e, s = map(np.array, zip(*[(p[0], p[1], p[y_at]) for p in sorted(pts)]))
                ax.loglog(
                    e,
                    s,
                    marker=marker,
                    color=color,
                    label=integ,
                    ms=5,
                    lw=1,
                    ls=":" if analytic else "-",
                    mfc="none" if analytic else color,
                )
                for ri, ei, si in zip(r, e, s):
                    ax.annotate(
                        f"{-math.log10(ri):.0f}", (ei, si), fontsize=FONT_MIN, xytext=(3, 3), textcoords="offset points"
                    )
            style_axes(ax, xlabel, ylabel, title)
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
            ax.scatter(
                x, y, marker=marker, facecolors="none", edgecolors=color, s=50, label=f"{integ}, tiny masses (k = 1e4)"
            )
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
    style_axes(
        ax,
        "fastest rod rate sqrt(k / m) (1/s)",
        "right-hand-side evaluations (count)",
        "stiff rods: cost of one horizon",
    )
    legend_outside(fig, title="integrator")
    return fig


def forward_figures(res: ForwardResults) -> dict[str, object]:
    """``stability-work-precision.png`` and ``stability-stiff.png``."""
    first = next(iter(res.growth), None)
    rt_series: dict[str, list] = {}
    for rt in res.round_trips:
        if rt.case == first:
            rt_series.setdefault(rt.integrator, []).append((rt.rtol, rt.error, rt.sim.seconds, rt.sim.nfev))
    for rt in res.analytic_trips:
        if rt.case == first and rt.sim.ok:
            rt_series.setdefault(rt.integrator + ANALYTIC, []).append((rt.rtol, rt.error, rt.sim.seconds, rt.sim.nfev))
    en_series: dict[str, list] = {}
    e_first = res.energy[0].case if res.energy else None
    for en in res.energy:
        if en.case == e_first:
            en_series.setdefault(en.integrator, []).append((en.rtol, en.drift / en.scale, en.sim.seconds, en.sim.nfev))
    st_series: dict[str, list] = {}
    for sr in res.stiff_wp:
        if sr.solved:
            st_series.setdefault(sr.integrator, []).append((sr.rtol, sr.error, sr.sim.seconds, sr.sim.nfev))
    for sr in res.analytic_stiff:
        if sr.solved and res.stiff_wp and sr.case == res.stiff_wp[0].case:
            st_series.setdefault(sr.integrator + ANALYTIC, []).append((sr.rtol, sr.error, sr.sim.seconds, sr.sim.nfev))
    panels = [
        (f"round trip: {first}", "max |q - q*| (rad, m)", rt_series),
        (f"energy drift: {e_first}", "max |E - E0| / max T (dimensionless)", en_series),
    ]
    if st_series:
        panels.append((f"stiff: {res.stiff_wp[0].case}", "max |q(H) - q_ref(H)| (rad, m)", st_series))
    from exo_bench.bench.output.suite_reports import STABILITY_FORWARD_FIGURES as NAMES

    return {
        NAMES[0]: work_precision_figure(panels),
        NAMES[1]: stiff_figure(res.stiff),
    }
