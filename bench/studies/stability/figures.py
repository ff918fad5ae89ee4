"""Every figure of ``reports/stability.md``: relative errors and condition numbers per family, and the
forward-dynamics study's work-precision diagrams and stiff rods.

The rules every stability and forward-dynamics figure follows (checked by tests/test_stability.py):
text of at least :data:`FONT_MIN` pt (the PNG is written at ``bench.reporting.PNG_DPI``), one colour
per method that no threshold reuses (thresholds are grey or black dashed lines with a legend
entry), the legend outside every data area, every axis labelled with its unit.
"""

from __future__ import annotations

import math

import numpy as np

from exo_bench.bench.output.figures.palette import method_color
from exo_bench.bench.studies.stability.cases import COND_ILL, COND_SINGULAR, REL_DEGRADED, REL_UNUSABLE
from exo_bench.bench.studies.stability.evaluation import FamilyResult
from exo_bench.bench.studies.stability.forward_evaluation import ForwardResults, StiffRun


#: The smallest text on a figure, in points (9 pt at 150 dpi is 19 px).
FONT_MIN = 9.0
#: Colours of the conditioning figure's series (methods take their own colour, palette.method_color);
#: grey and black are kept for the thresholds.
_SERIES_COLOURS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf", "#bcbd22")
#: Thresholds: the lower (degraded, ill-conditioned) grey, the upper (unusable, singular) black.
THRESHOLD_LOW = {"color": "#7f7f7f", "ls": "--", "lw": 1.2}
THRESHOLD_HIGH = {"color": "black", "ls": "--", "lw": 1.2}
#: Sub-series of a family are told apart by marker (line styles stay solid: dashed means threshold).
_SERIES_MARKERS = ("o", "s", "^", "v", "D")
_MARKER_NAMES = {"o": "circles", "s": "squares", "^": "triangles up", "v": "triangles down", "D": "diamonds"}

FLOOR = 1e-18  # errors of exactly 0 are drawn here on the log axes


def _xpos(xs: np.ndarray) -> np.ndarray:
    """Plot positions on a log axis: 0 (exactly at the singularity) goes two decades below the
    smallest positive value."""
    pos = xs[xs > 0]
    zero_at = (pos.min() / 100.0) if pos.size else 1e-18
    return np.where(xs > 0, xs, zero_at)


_XLABELS = {
    "near-vertical rods": "distance from vertical d = pi/2 - psi (rad)",
    "removable singularities of eq. (18)": "distance d from the singularity (rad)",
    "very short and very long rods": "rod length L (m)",
    "mass ratios": "mass ratio r: swing leg masses x r (dimensionless)",
    "large n": "number of links n (links)",
    "fast gaits": "gait period T (s)",
}


def _swept(families: list[FamilyResult]) -> list[FamilyResult]:
    return [fr for fr in families if any(math.isfinite(cr.case.x) for cr in fr.results)]


def _series_title(fr: FamilyResult, series: list[str]) -> str:
    """The family's name, then one line per sub-series saying its marker."""
    if len(series) < 2:
        return fr.name
    marks = [_MARKER_NAMES[_SERIES_MARKERS[i % len(_SERIES_MARKERS)]] for i in range(len(series))]
    return "\n".join([fr.name] + [f"{m}: {s}" for m, s in zip(marks, series)])


def style_axes(ax, xlabel: str, ylabel: str, title: str | None = None) -> None:
    """Axis labels, title and ticks at readable sizes, a light grid."""
    ax.set_xlabel(xlabel, fontsize=FONT_MIN)
    ax.set_ylabel(ylabel, fontsize=FONT_MIN)
    if title is not None:
        ax.set_title(title, fontsize=FONT_MIN + 1)
    ax.tick_params(which="both", labelsize=FONT_MIN)
    ax.grid(True, which="major", lw=0.3)


def legend_outside(fig, handles=None, labels=None, title: str | None = None, below: bool = False):
    """One legend for the whole figure, outside every axes: to the right, or ``below`` them in
    columns (constrained layout makes room)."""
    if handles is None:
        seen: dict[str, object] = {}
        for ax in fig.axes:
            for h, lab in zip(*ax.get_legend_handles_labels()):
                seen.setdefault(lab, h)
        labels, handles = list(seen), list(seen.values())
    where = {"loc": "outside lower center", "ncols": 4} if below else {"loc": "outside right upper"}
    return fig.legend(handles, labels, fontsize=FONT_MIN, title=title, title_fontsize=FONT_MIN, **where)


def _family_panels(families: list[FamilyResult]):
    """A 2 x 3 figure with one panel per swept family (unused panels hidden), and per panel
    ``(ax, family, cases with a finite x, sub-series names, x position of each case by id)``."""
    from matplotlib.figure import Figure

    fams = _swept(families)
    fig = Figure(figsize=(15, 10.5), layout="constrained")
    axes = fig.subplots(2, 3).ravel()
    for ax in axes[len(fams) :]:
        ax.set_visible(False)
    panels = []
    for ax, fr in zip(axes, fams):
        cases = [cr for cr in fr.results if math.isfinite(cr.case.x)]
        series = list(dict.fromkeys(cr.case.series for cr in cases))
        allx = _xpos(np.array([cr.case.x for cr in cases]))
        panels.append((ax, fr, cases, series, {id(cr): x for cr, x in zip(cases, allx)}))
    return fig, panels


def _xlabel(fr: FamilyResult, cases) -> str:
    zero = "\n(0 drawn at the far left)" if any(cr.case.x == 0 for cr in cases) else ""
    return _XLABELS.get(fr.name, "swept parameter") + zero


def families_figure(families: list[FamilyResult], methods: list[str]):
    """Relative error against the swept parameter, one panel per family, one colour per method,
    one marker per sub-series; cases with NaN/Inf are crosses at 1 (no line point)."""
    fig, panels = _family_panels(families)
    for ax, fr, cases, series, xmap in panels:
        for m in methods:
            color = method_color(m, methods)
            for si, s in enumerate(series):
                crs = sorted(
                    [cr for cr in cases if cr.case.series == s and m in cr.rows and cr.rows[m].status == "ok"],
                    key=lambda cr: xmap[id(cr)],
                )
                if not crs:
                    continue
                xs = np.array([xmap[id(cr)] for cr in crs])
                ys = np.array([np.nan if cr.rows[m].nonfinite else max(cr.rows[m].rel_err, FLOOR) for cr in crs])
                ax.loglog(
                    xs, ys, color=color, ls="-", marker=_SERIES_MARKERS[si % len(_SERIES_MARKERS)], ms=4, lw=1, label=m
                )
                bad = [i for i, cr in enumerate(crs) if cr.rows[m].nonfinite]
                if bad:
                    ax.scatter(
                        xs[bad],
                        np.full(len(bad), 1.0),
                        marker="x",
                        color=color,
                        s=50,
                        zorder=5,
                        label=f"NaN/Inf, drawn at 1 ({m})",
                    )
        ax.axhline(REL_UNUSABLE, **THRESHOLD_HIGH, label=f"unusable above {REL_UNUSABLE:.0e}")
        ax.axhline(REL_DEGRADED, **THRESHOLD_LOW, label=f"degraded above {REL_DEGRADED:.0e}")
        ax.set_ylim(FLOOR / 3, 30)
        style_axes(ax, _xlabel(fr, cases), "relative error vs 50 digits (dimensionless)", _series_title(fr, series))
    legend_outside(fig, title="methods (colours) and thresholds (dashed)", below=True)
    fig.suptitle(
        f"Inverse dynamics: max |tau - ref| / max |ref| per case (exactly 0 drawn at {FLOOR:.0e})",
        fontsize=FONT_MIN + 2,
    )
    return fig


def conditioning_figure(families: list[FamilyResult]):
    """cond(M) and the equilibrated cond against the swept parameter, per family; an infinite
    condition number is drawn as a triangle at the top."""
    fig, panels = _family_panels(families)
    for ax, fr, cases, series, xmap in panels:
        finite = [v for cr in cases for v in (cr.cond_raw, cr.cond_eq) if math.isfinite(v)]
        top = 10.0 ** math.ceil(math.log10(max(finite + [COND_SINGULAR]))) * 100
        for si, s in enumerate(series):
            crs = sorted([cr for cr in cases if cr.case.series == s], key=lambda cr: xmap[id(cr)])
            xs = np.array([xmap[id(cr)] for cr in crs])
            marker = _SERIES_MARKERS[si % len(_SERIES_MARKERS)]
            for attr, color, lab in (
                ("cond_raw", _SERIES_COLOURS[0], "cond(M), SI units"),
                ("cond_eq", _SERIES_COLOURS[2], "equilibrated cond(D^-1/2 M D^-1/2), D = diag M"),
            ):
                v = np.array([getattr(cr, attr) for cr in crs])
                ax.loglog(
                    xs, np.where(np.isfinite(v), v, np.nan), color=color, ls="-", marker=marker, ms=4, lw=1, label=lab
                )
                inf = ~np.isfinite(v)
                if inf.any():
                    ax.scatter(
                        xs[inf],
                        np.full(inf.sum(), top),
                        marker="^",
                        color=color,
                        s=30,
                        zorder=5,
                        label=f"{lab.split(',')[0]} = inf (drawn at the top)",
                    )
            sing = [i for i, cr in enumerate(crs) if cr.singular_samples]
            if sing:
                ys = [crs[i].cond_raw if math.isfinite(crs[i].cond_raw) else top for i in sing]
                ax.scatter(
                    xs[sing],
                    ys,
                    marker="o",
                    facecolors="none",
                    edgecolors=_SERIES_COLOURS[1],
                    s=70,
                    zorder=6,
                    label="singular (exact cause)",
                )
        ax.axhline(COND_SINGULAR, **THRESHOLD_HIGH, label=f"numerically singular from {COND_SINGULAR:.0e}")
        ax.axhline(COND_ILL, **THRESHOLD_LOW, label=f"ill-conditioned from {COND_ILL:.0e}")
        ax.set_ylim(1, top * 10)
        style_axes(ax, _xlabel(fr, cases), "condition number, 2-norm (dimensionless)", _series_title(fr, series))
    legend_outside(fig, title="condition numbers and thresholds (dashed)", below=True)
    fig.suptitle("Condition number of the mass matrix (CRBA), largest over each case's states", fontsize=FONT_MIN + 2)
    return fig


# Forward-dynamics study, the figures: work-precision diagrams and stiff rods.

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
    from exo_bench.bench.output.publish import STABILITY_FORWARD_FIGURES as NAMES

    return {
        NAMES[0]: work_precision_figure(panels),
        NAMES[1]: stiff_figure(res.stiff),
    }
