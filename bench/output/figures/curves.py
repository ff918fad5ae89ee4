"""The curves of a study: the NET joint moments (the paper's Fig. 7, the numbers of the scene report),
the rod forces (Fig. 8) and every method minus the reference, in panels grouped by scale.

**Which moments** the differences compare: those of the joint coordinates, ``tau_joint = G^-T tau``
(:mod:`exo_bench.models.engines.joint_coordinates`), per method; not the generalised forces of the absolute
angles, and not the net joint moments (which depend on the motion alone). Every figure says in its
title which it shows, with units and signs.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from exo_bench.bench.output.figures.palette import LINK_COLORS, TEXT_PT, TITLE_PT, link_color, method_color
from exo_bench.models.engines.joint_coordinates import force_labels, joint_basis, moments_and_forces
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.kinematics import moment_components, net_joint_loads


if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study

#: Panels of Figs. 7 and 8 span at most this factor between their largest and smallest maximum.
SCALE_RATIO = 10.0
#: A curve whose ``max |value|`` is below this fraction of the largest one is reported as zero.
ZERO_FRACTION = 1e-9

_STYLES = ("--", ":", "-.", (0, (5, 1, 1, 1)), (0, (1, 3)), (0, (8, 3)))


# ----------------------------------------------------------------------------- grouping by scale
@dataclass(frozen=True)
class ScaleGroups:
    """Curves grouped by the scale of their absolute maxima, as in the paper's Figs. 7 and 8."""

    groups: tuple[tuple[int, ...], ...]  # curve indices per panel, largest scale first, each by decreasing max
    zero: tuple[int, ...]  # curves that are zero (max below ZERO_FRACTION of the largest)
    maxima: np.ndarray  # max |value| of every curve


def group_by_scale(maxima, ratio: float = SCALE_RATIO, zero_fraction: float = ZERO_FRACTION) -> ScaleGroups:
    """Group curves so that each panel spans at most a factor ``ratio`` of maxima.

    Curves are sorted by ``max |value|``; a group wider than ``ratio`` is split at the largest
    ratio between consecutive maxima, recursively (natural breaks on a log scale). So curves of
    similar size share a panel and every boundary between panels is at least as wide as any gap
    inside its two neighbours. Curves below ``zero_fraction`` of the largest maximum are zero.
    """
    m = np.asarray(maxima, dtype=float)
    if m.ndim != 1 or not np.all(np.isfinite(m)) or np.any(m < 0):
        raise ValueError(f"group_by_scale: field 'maxima': expected finite values >= 0, got {m!r}")
    if not ratio > 1:
        raise ValueError(f"group_by_scale: field 'ratio': expected > 1, got {ratio!r}")
    top = float(m.max()) if m.size else 0.0
    order = [int(i) for i in np.argsort(-m, kind="stable")]
    live = [i for i in order if top > 0 and m[i] >= zero_fraction * top]
    zero = tuple(i for i in order if i not in live)

    def split(idx: list[int]) -> list[list[int]]:
        if len(idx) <= 1 or m[idx[0]] <= ratio * m[idx[-1]]:
            return [idx]
        gaps = [m[idx[k]] / m[idx[k + 1]] for k in range(len(idx) - 1)]
        cut = int(np.argmax(gaps)) + 1
        return split(idx[:cut]) + split(idx[cut:])

    groups = tuple(tuple(g) for g in split(live)) if live else ()
    return ScaleGroups(groups, zero, m)


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def scale_caption(groups: ScaleGroups, g: int, unit: str, sym: str = "·") -> str:
    """``max |M| 49.1–126 N·m``: the range of the maxima of panel ``g``."""
    idx = groups.groups[g]
    hi, lo = groups.maxima[idx[0]], groups.maxima[idx[-1]]
    return f"max |{sym}| {_fmt(hi)} {unit}" if len(idx) == 1 else f"max |{sym}| {_fmt(lo)}–{_fmt(hi)} {unit}"


# ----------------------------------------------------------------------------- captions
def reference_method(study: Study) -> str | None:
    """The study's reference if it produced tau, else the first method that did (None if none did)."""
    ok = study.ok_methods()
    if study.reference in ok:
        return study.reference
    return ok[0] if ok else None


def _methods_line(study: Study) -> str:
    ok = study.ok_methods()
    ref = reference_method(study)
    parts = [f"{m} (solid)" if m == ref else f"{m} ({_style_name(ok, ref, m)})" for m in ok]
    return "methods: " + (", ".join(parts) if parts else "none succeeded")


def _not_run_line(study: Study) -> str:
    bad = [
        f"{m}: skipped ({r.skipped})" if r.skipped else f"{m}: failed ({r.error})"
        for m, r in study.results.items()
        if not r.ok
    ]
    return "; ".join(bad)


def nonfinite_notes(study: Study) -> list[str]:
    """One warning per method whose tau holds NaN or infinite values (they cannot be drawn)."""
    out = []
    for m in study.ok_methods():
        bad = ~np.isfinite(study.tau(m))
        if bad.any():
            rows = np.flatnonzero(bad.any(axis=1))
            out.append(
                f"WARNING: {m} returned {int(bad.sum())} non-finite value(s) at {rows.size} instant(s), "
                f"first at t = {study.motion.t[rows[0]]:.4g} s; they are not drawn"
            )
    return out


def _style_of(ok: list[str], ref: str | None, m: str):
    others = [x for x in ok if x != ref]
    return "-" if m == ref else _STYLES[others.index(m) % len(_STYLES)]


def _style_name(ok, ref, m) -> str:
    st = _style_of(ok, ref, m)
    return (
        {"--": "dashed", ":": "dotted", "-.": "dash-dot"}.get(st, "patterned") if isinstance(st, str) else "patterned"
    )


def _check_ok(study: Study) -> str:
    """The method the figures draw against (:func:`reference_method`); ValueError when no method produced tau."""
    ref = reference_method(study)
    if ref is None:
        why = _not_run_line(study) or "no methods were run"
        raise ValueError(f"study {study.name!r}: no method produced tau ({why}); nothing to plot")
    return ref


#: Characters per title line: 10 pt across an 11.5 in wide figure, with a margin (a predicted step's
#: motion label is long: its title once ran off both sides of the figure).
TITLE_WIDTH = 105


def _header(study: Study, what: str) -> str:
    """The figure's title: the study, its model and motion (in lines that fit), then ``what`` it shows
    (its lines as the figure breaks them)."""
    mech = study.mechanism
    first = f"{study.name} ({mech.dim}D, {mech.nlinks} links) — {study.motion_label}"
    return "\n".join([*textwrap.wrap(first, TITLE_WIDTH, break_on_hyphens=False), what])


# ----------------------------------------------------------------------------- Figs. 7 and 8
def _curves_figure(study: Study, ratio: float = SCALE_RATIO) -> Figure:
    ref = _check_ok(study)
    mech = study.mechanism
    ok = study.ok_methods()
    data = {m: moments_and_forces(mech, study.tau(m))[1] for m in ok}
    labels, unit, sym = force_labels(mech), "N", "F"
    what = (
        "Longitudinal rod forces (the paper's Fig. 8) in N: F_k along rod k, positive where the rod is pushed\n"
        "longer (the same in joint and in absolute coordinates: l_k maps to itself)"
    )
    t = study.motion.t
    # The reference's scales decide the panels; other methods overlay it. NaN are reported, not grouped.
    finite = np.where(np.isfinite(data[ref]), np.abs(data[ref]), 0.0)
    groups = group_by_scale(finite.max(axis=0), ratio)
    rows = max(len(groups.groups), 1)
    notes = [_methods_line(study) + f"; panels grouped by the scale of max |{sym}| (each spans at most {ratio:g}×)"]
    if groups.zero:
        notes.append(
            f"zero throughout (max |{sym}| < {ZERO_FRACTION:g} of the largest): "
            + ", ".join(labels[j] for j in groups.zero)
        )
    if _not_run_line(study):
        notes.append("not shown: " + _not_run_line(study))
    notes = _wrap_notes(notes + nonfinite_notes(study))
    fig = Figure(figsize=(11.5, 1.6 + 2.35 * rows + 0.2 * len(notes)), layout="constrained")
    axes, note_ax = _panels(fig, rows, len(notes))
    curve_color = curve_colors(mech, "forces")
    for g, ax in enumerate(axes):
        idx = groups.groups[g] if groups.groups else ()
        for j in idx:
            for m in ok:
                ax.plot(
                    t,
                    data[m][:, j],
                    color=curve_color[j],
                    ls=_style_of(ok, ref, m),
                    lw=1.8 if m == ref else 1.2,
                    label=labels[j] if m == ref else None,
                    gid=f"{m}:{labels[j]}",
                )
        ax.set_ylabel(f"{sym} ({unit})", fontsize=TEXT_PT)
        ax.set_title(scale_caption(groups, g, unit, sym) if groups.groups else "all zero", loc="left", fontsize=TEXT_PT)
        ax.grid(True, alpha=0.3)
        ax.axhline(0.0, color="k", lw=0.6, alpha=0.5)
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=TEXT_PT, frameon=False)
        ax.set_xlim(t[0], t[-1])
        ax.tick_params(labelsize=TEXT_PT)
    axes[-1].set_xlabel("time t (s)", fontsize=TEXT_PT)
    if len(ok) > 1:  # line style = method, outside the plots
        handles = [Line2D([], [], color="0.3", ls=_style_of(ok, ref, m)) for m in ok]
        fig.legend(
            handles,
            ok,
            loc="outside right lower",
            fontsize=TEXT_PT,
            title="method (line style)",
            title_fontsize=TEXT_PT,
            frameon=False,
        )
    fig.suptitle(_header(study, what), fontsize=TITLE_PT)
    _write_notes(note_ax, notes)
    return fig


def _panels(fig: Figure, rows: int, note_lines: int):
    """``rows`` stacked plots sharing the time axis, and a text strip below them for notes."""
    gs = fig.add_gridspec(rows + 1, 1, height_ratios=[1.0] * rows + [0.08 + 0.09 * note_lines])
    axes = [fig.add_subplot(gs[0, 0])]
    for r in range(1, rows):
        axes.append(fig.add_subplot(gs[r, 0], sharex=axes[0]))
    for ax in axes[:-1]:
        ax.tick_params(labelbottom=False)
    note_ax = fig.add_subplot(gs[rows, 0])
    note_ax.set_axis_off()
    return axes, note_ax


#: Characters per line of a figure's notes: 9 pt text across the plots of an 11.5 in wide figure.
NOTE_WIDTH = 120


def _wrap_notes(lines: list[str], width: int = NOTE_WIDTH) -> list[str]:
    """The notes broken into lines that fit under the plots (continuation lines indented)."""
    out: list[str] = []
    for line in lines:
        out += textwrap.wrap(line, width, subsequent_indent="  ", break_on_hyphens=False) or [""]
    return out


def _write_notes(ax, lines: list[str]) -> None:
    """The (wrapped) notes in the strip below the plots. The text takes no part in the layout: a long
    line would otherwise make constrained layout shrink the whole column of plots to fit it."""
    txt = ax.text(
        0.0, 1.0, "\n".join(lines), transform=ax.transAxes, ha="left", va="top", fontsize=TEXT_PT, color="0.2"
    )
    txt.set_in_layout(False)


def curve_colors(mech: Mechanism, kind: str) -> list[str]:
    """Colour of each curve of ``kind`` ("moments" or "forces"): a link's colour for its azimuth
    joint and rod force, the palette entry half-way round for its elevation joint (3D)."""
    jb = joint_basis(mech)
    rows = jb.moment_rows if kind == "moments" else jb.force_rows
    return [link_color(jb.link[r] + (len(LINK_COLORS) // 2 if jb.kind[r] == "psi" else 0)) for r in rows]


def forces_figure(study: Study, ratio: float = SCALE_RATIO) -> Figure:
    """The longitudinal rod forces along the motion (the paper's Fig. 8), panels grouped by scale."""
    return _curves_figure(study, ratio)


# ----------------------------------------------------------------------------- differences
def differences_figure(study: Study) -> Figure | None:
    """Largest ``|method - reference|`` over the joints at each instant, joint moments and rod forces
    separately (log scale). ``None`` when fewer than two methods succeeded."""
    ok = study.ok_methods()
    ref = reference_method(study)
    others = [m for m in ok if m != ref]
    if ref is None or not others:
        return None
    mech, t = study.mechanism, study.motion.t
    notes = [
        f"reference: {ref}; one colour per method (legend); log scale: an instant where a method equals "
        f"{ref} exactly (Δ = 0) leaves a gap"
    ] + (["not shown: " + _not_run_line(study)] if _not_run_line(study) else [])
    notes = _wrap_notes(notes + nonfinite_notes(study))
    fig = Figure(figsize=(11.5, 5.6 + 0.2 * len(notes)), layout="constrained")
    axes, note_ax = _panels(fig, 2, len(notes))
    for ax, part, unit in ((axes[0], 0, "N·m"), (axes[1], 1, "N")):
        for m in others:
            d = np.abs(moments_and_forces(mech, study.tau(m) - study.tau(ref))[part]).max(axis=1)
            dmax = float(np.nanmax(d)) if np.isfinite(d).any() else float("nan")
            scale = float(np.nanmax(np.abs(moments_and_forces(mech, study.tau(ref))[part]))) or 1.0
            color = method_color(m, ok)
            if dmax == 0.0:
                ax.plot([], [], color=color, label=f"{m} − {ref}: identical (0)")
                continue
            ax.semilogy(
                t,
                np.where(d > 0, d, np.nan),
                color=color,
                lw=1.2,
                gid=f"diff:{m}",
                label=f"{m} − {ref}: max {dmax:.2g} {unit}\n({dmax / scale:.1e} of the largest {ref} value)",
            )
        name = "joint-coordinate moments Δτ_joint" if part == 0 else "rod forces ΔF"
        ax.set_ylabel(f"max |Δ| ({unit})", fontsize=TEXT_PT)
        ax.set_title(f"{name}: largest |method − {ref}| over the joints", loc="left", fontsize=TEXT_PT)
        ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=TEXT_PT)
        ax.legend(fontsize=TEXT_PT, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    axes[-1].set_xlabel("time t (s)", fontsize=TEXT_PT)
    axes[-1].set_xlim(t[0], t[-1])
    fig.suptitle(
        _header(
            study,
            f"Differences between methods, |method − {ref}| (no sign), in the joint-coordinate moments "
            "τ_joint = G⁻ᵀ τ (N·m) and rod forces (N)",
        ),
        fontsize=TITLE_PT,
    )
    _write_notes(note_ax, notes)
    return fig


# The joint moments figure (the paper's Fig. 7): NET joint moments, the numbers of the scene report.

if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study

#: The unit of every net-moment curve: N·m per kg of the model's total mass (as the report's table).
UNIT = "N·m/kg"


def net_moment_curves(study: Study) -> list[tuple[str, str, np.ndarray]]:
    """``(component, sign convention, (S, n) array in N·m/kg)`` of the study's motion."""
    mech, mo = study.mechanism, study.motion
    M, _ = net_joint_loads(mech, mo.q, mo.qd, mo.qdd)
    return [(name, sign, values / mech.total_mass) for name, sign, values in moment_components(mech, M)]


def joint_labels(study: Study) -> list[str]:
    """One legend label per joint: the link whose start it is (``"joint 1: start of stance_shin"``)."""
    return [f"joint {k + 1}: start of {name}" for k, name in enumerate(study.mechanism.names)]


def draw_net_moments(ax, study: Study, component: tuple[str, str, np.ndarray], labels: list[str]) -> None:
    """One component's curves on ``ax``, one colour per joint (its link's), titled with its sign."""
    name, sign, values = component
    t = study.motion.t
    for k in range(values.shape[1]):
        ax.plot(t, values[:, k], color=link_color(k), lw=1.5, label=labels[k], gid=f"net:{name}:{k}")
    ax.set_title(f"{name} component ({sign})", loc="left", fontsize=TEXT_PT)
    ax.set_ylabel(f"M / m ({UNIT})", fontsize=TEXT_PT)
    ax.axhline(0.0, color="k", lw=0.6, alpha=0.5)
    ax.grid(True, alpha=0.3)
    ax.set_xlim(t[0], t[-1])
    ax.tick_params(labelsize=TEXT_PT)


def moments_figure(study: Study, ratio: float | None = None) -> Figure:
    """Net joint moments along the motion, one panel per component (``ratio``: unused, kept for the
    figures' common signature)."""
    _check_ok(study)  # a study without any tau has nothing to show (its motion alone is no scene result)
    curves = net_moment_curves(study)
    labels = joint_labels(study)
    mech = study.mechanism
    notes = [
        f"per kg of the model's {mech.total_mass:.4g} kg; from the motion's point masses (models/mechanism/kinematics.py), "
        "the numbers of the scene report's Plausibility table; the methods' differences: the differences figure"
    ] + (["not run: " + _not_run_line(study)] if _not_run_line(study) else [])
    notes = _wrap_notes(notes + nonfinite_notes(study))
    fig = Figure(figsize=(11.5, 1.9 + 2.35 * len(curves) + 0.2 * len(notes)), layout="constrained")
    axes, note_ax = _panels(fig, len(curves), len(notes))
    for ax, component in zip(axes, curves):
        draw_net_moments(ax, study, component, labels)
    axes[-1].set_xlabel("time t (s)", fontsize=TEXT_PT)
    fig.legend(
        *axes[0].get_legend_handles_labels(),
        loc="outside right upper",
        fontsize=TEXT_PT,
        title="joint (link colour)",
        title_fontsize=TEXT_PT,
        frameon=False,
    )
    what = (
        "Net joint moments (the paper's Fig. 7) in N·m/kg: the moment the parent side exerts on everything\n"
        "beyond the joint, about the joint; not the generalised forces τ of the absolute angles"
    )
    fig.suptitle(_header(study, what), fontsize=TITLE_PT)
    _write_notes(note_ax, notes)
    return fig
