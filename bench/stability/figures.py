"""Stability study, the figures: relative errors and condition numbers per family.
"""

from __future__ import annotations

import math

import numpy as np

from exo_bench.bench.stability.cases import COND_ILL, COND_SINGULAR, REL_DEGRADED, REL_UNUSABLE
from exo_bench.bench.stability.evaluation import FamilyResult


# ----------------------------------------------------------------------------- figures
_MCOLORS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf")


_SERIES_STYLES = ("-", "--", ":", "-.")


FLOOR = 1e-18  # errors of exactly 0 are drawn here on the log axes


def _xpos(xs: np.ndarray) -> np.ndarray:
    """Plot positions on a log axis: 0 (exactly at the singularity) goes two decades below the
    smallest positive value."""
    pos = xs[xs > 0]
    zero_at = (pos.min() / 100.0) if pos.size else 1e-18
    return np.where(xs > 0, xs, zero_at)


_XLABELS = {"near-vertical rods": "d = pi/2 - psi (rad)", "removable singularities of eq. (18)": "distance d (rad)",
            "very short and very long rods": "L (m)", "mass ratios": "r (swing leg masses x r)", "large n": "n",
            "fast gaits": "T (s)"}


def _swept(families: list[FamilyResult]) -> list[FamilyResult]:
    return [fr for fr in families if any(math.isfinite(cr.case.x) for cr in fr.results)]


def _series_title(fr: FamilyResult, series: list[str]) -> str:
    if len(series) < 2:
        return fr.name
    marks = {"-": "solid", "--": "dashed", ":": "dotted", "-.": "dash-dot"}
    return fr.name + "\n" + "; ".join(f"{marks[_SERIES_STYLES[i % 4]]}: {s}" for i, s in enumerate(series))


def _family_panels(families: list[FamilyResult]):
    """A 2 x 3 figure with one panel per swept family (unused panels hidden), and per panel
    ``(ax, family, cases with a finite x, sub-series names, x position of each case by id)``."""
    from matplotlib.figure import Figure

    fams = _swept(families)
    fig = Figure(figsize=(13, 7.2), layout="constrained")
    axes = fig.subplots(2, 3).ravel()
    for ax in axes[len(fams):]:
        ax.set_visible(False)
    panels = []
    for ax, fr in zip(axes, fams):
        cases = [cr for cr in fr.results if math.isfinite(cr.case.x)]
        series = list(dict.fromkeys(cr.case.series for cr in cases))
        allx = _xpos(np.array([cr.case.x for cr in cases]))
        panels.append((ax, fr, cases, series, {id(cr): x for cr, x in zip(cases, allx)}))
    return fig, panels


def families_figure(families: list[FamilyResult], methods: list[str]):
    """Relative error against the swept parameter, one panel per family, one colour per method,
    one line style per sub-series; cases with NaN/Inf are red crosses at 1 (no line point)."""
    fig, panels = _family_panels(families)
    for ax, fr, cases, series, xmap in panels:
        nan_label = True
        for mi, m in enumerate(methods):
            for si, s in enumerate(series):
                crs = sorted([cr for cr in cases if cr.case.series == s and m in cr.rows and cr.rows[m].status == "ok"],
                             key=lambda cr: xmap[id(cr)])
                if not crs:
                    continue
                xs = np.array([xmap[id(cr)] for cr in crs])
                ys = np.array([np.nan if cr.rows[m].nonfinite else max(cr.rows[m].rel_err, FLOOR) for cr in crs])
                ax.loglog(xs, ys, color=_MCOLORS[mi % len(_MCOLORS)], ls=_SERIES_STYLES[si % 4], marker=".",
                          lw=1, label=m if si == 0 else None)
                bad = [i for i, cr in enumerate(crs) if cr.rows[m].nonfinite]
                if bad:
                    ax.scatter(xs[bad], np.full(len(bad), 1.0), marker="x", color=_MCOLORS[mi % len(_MCOLORS)],
                               s=40, zorder=5, label=f"NaN/Inf ({m})" if nan_label else None)
                    nan_label = False
        ax.axhline(REL_UNUSABLE, color="red", lw=0.6, ls="--")
        ax.axhline(REL_DEGRADED, color="orange", lw=0.6, ls="--")
        ax.set_ylim(FLOOR / 3, 30)
        ax.set_title(_series_title(fr, series), fontsize=8)
        zero = " (0 at the far left)" if any(cr.case.x == 0 for cr in cases) else ""
        ax.set_xlabel(_XLABELS.get(fr.name, "parameter") + zero, fontsize=7)
        ax.set_ylabel("relative error vs 50 digits", fontsize=7)
        ax.tick_params(which="both", labelsize=7)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=6, loc="center right")
    fig.suptitle("Inverse dynamics against the 50-digit reference (dashed: degraded / unusable thresholds; "
                 f"errors of 0 drawn at {FLOOR:.0e}; crosses: NaN/Inf)", fontsize=9)
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
            ls = _SERIES_STYLES[si % 4]
            for attr, color, lab in (("cond_raw", "#1f77b4", "cond(M)"), ("cond_eq", "#2ca02c", "cond_eq")):
                v = np.array([getattr(cr, attr) for cr in crs])
                ax.loglog(xs, np.where(np.isfinite(v), v, np.nan), color=color, ls=ls, marker=".", lw=1,
                          label=lab if si == 0 else None)
                inf = ~np.isfinite(v)
                if inf.any():
                    ax.scatter(xs[inf], np.full(inf.sum(), top), marker="^", color=color, s=30, zorder=5,
                               label=f"{lab} = inf" if si == 0 else None)
            sing = [i for i, cr in enumerate(crs) if cr.singular_samples]
            if sing:
                ys = [crs[i].cond_raw if math.isfinite(crs[i].cond_raw) else top for i in sing]
                ax.scatter(xs[sing], ys, marker="o", facecolors="none", edgecolors="red", s=60, zorder=6,
                           label="singular (exact cause)" if si == 0 else None)
        ax.axhline(COND_ILL, color="orange", lw=0.6, ls="--")
        ax.axhline(COND_SINGULAR, color="red", lw=0.6, ls="--")
        ax.set_ylim(1, top * 10)
        ax.set_title(_series_title(fr, series), fontsize=8)
        zero = " (0 at the far left)" if any(cr.case.x == 0 for cr in cases) else ""
        ax.set_xlabel(_XLABELS.get(fr.name, "parameter") + zero, fontsize=7)
        ax.tick_params(which="both", labelsize=7)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=6)
    fig.suptitle("Condition number of the mass matrix from CRBA (dashed: ill-conditioned / numerically singular)",
                 fontsize=9)
    return fig

