"""Figures of a :class:`bench.study.Study`: the paper's Figs. 7-9 and the differences between methods.

* :func:`moments_figure` - the control moments in the joints (Fig. 7),
* :func:`forces_figure` - the longitudinal forces along the rods (Fig. 8),
* :func:`kinogram_figure` - stick-figure frames of the motion (Fig. 9),
* :func:`differences_figure` - every method minus the reference,
* :func:`overview_figure` - one picture of a scene (kinogram, moments, forces, differences).

**Which moments.** A study's ``tau`` are the generalised forces of the paper's *absolute*
angles (eq. 4 has ``M1 - M2`` on ``phi_1``). The physical moments in the joints (what Fig. 7
shows) are ``tau_joint = G^-T tau`` with ``G`` the constant map ``q_joint = G q`` of
:func:`models.pinocchio_backend.build_model`: each joint turns link k relative to its parent
(azimuth ``phi_k - phi_parent``; in 3D also the elevation ``psi_k``; the prismatic joint
``l_k``). The rod forces ``F_k`` are the same in both sets, because the column of ``G`` of
``l_k`` is a unit vector (``l_k`` maps to itself), so ``F_k = tau_joint[len_k] = tau[l_k]``.
Every figure says in its title which of the two it shows.

Figures are built with matplotlib's object API (no pyplot, no global backend switch) and are
saved atomically by :func:`save_figure`.
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from exo_bench.bench.reporting import save_figure  # noqa: F401 (re-exported: the scene figures' writer)
from exo_bench.bench.study import Study
from exo_bench.models.kinematics import point_mass_positions
from exo_bench.models.mechanism import Mechanism

#: Panels of Figs. 7 and 8 span at most this factor between their largest and smallest maximum.
SCALE_RATIO = 10.0
#: A curve whose max |value| is below this fraction of the largest one is reported as zero.
ZERO_FRACTION = 1e-9

_COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#17becf",
           "#bcbd22", "#7f7f7f")
#: One colour per method, the same in every figure (Dark2: none is a link colour, none is the grey or
#: black that thresholds use); methods not listed take the remaining ones in order.
METHOD_COLORS = {"pinocchio": "#1b9e77", "matrix": "#d95f02", "matrix-factored": "#7570b3", "matrix-paper": "#e7298a",
                 "recurrence": "#66a61e", "lagrange": "#e6ab02", "mujoco": "#a6761d", "drake": "#1f78b4"}
_SPARE_METHOD_COLORS = ("#b15928", "#6a3d9a", "#882255", "#999933")
#: Smallest text in any figure (points): 9 pt at 150 dpi is 19 px high.
TEXT_PT = 9.0
TITLE_PT = 10.0
_STYLES = ("--", ":", "-.", (0, (5, 1, 1, 1)), (0, (1, 3)), (0, (8, 3)))
_JOINT = re.compile(r"L(\d+)_(phi|psi|len)$")
_SYMBOL = {"phi": "Mφ", "psi": "Mψ", "len": "F"}


def link_color(i: int) -> str:
    """The colour of link ``i`` (0-based) in every figure and recording."""
    return _COLORS[i % len(_COLORS)]


def method_color(method: str, others: list[str] | tuple[str, ...] = ()) -> str:
    """The colour of ``method`` in every figure: :data:`METHOD_COLORS`, or for a method not listed
    there the spare colour of its place among the unlisted ``others``."""
    if method in METHOD_COLORS:
        return METHOD_COLORS[method]
    unlisted = [m for m in others if m not in METHOD_COLORS]
    k = unlisted.index(method) if method in unlisted else 0
    return _SPARE_METHOD_COLORS[k % len(_SPARE_METHOD_COLORS)]


# ----------------------------------------------------------------------------- joint quantities
@dataclass(frozen=True, eq=False)
class JointBasis:
    """Pinocchio's joint coordinates of a mechanism and the map to them.

    ``tau_joint = tau @ G_inv`` (row vectors) converts generalised forces of the paper's absolute
    angles into the physical joint moments and rod forces, rows named by ``names``.
    """

    names: tuple[str, ...]       # Pinocchio joint names, e.g. "L1_phi", "L1_psi", "L1_len"
    labels: tuple[str, ...]      # "Mψ1 stance_shin", "F1 stance_shin", ...
    link: tuple[int, ...]        # 0-based link of each joint
    kind: tuple[str, ...]        # "phi", "psi" or "len"
    G_inv: np.ndarray            # (dof, dof)
    moment_rows: tuple[int, ...]  # joint rows that are moments (revolute joints)
    force_rows: tuple[int, ...]   # joint rows that are rod forces (prismatic joints), link order


@lru_cache(maxsize=64)
def joint_basis(mech: Mechanism) -> JointBasis:
    """The joint coordinates of ``mech`` (built once per mechanism)."""
    from exo_bench.models.pinocchio_backend import build_model

    pm = build_model(mech)
    G = np.asarray(pm.G, dtype=float)
    if G.shape != (mech.dof, mech.dof):
        raise ValueError(f"{mech.name}: joint map G: expected shape ({mech.dof}, {mech.dof}), got {G.shape}")
    links, kinds, labels = [], [], []
    for name in pm.joint_names:
        m = _JOINT.match(name)
        if m is None:
            raise ValueError(f"{mech.name}: joint name {name!r}: expected L<k>_phi, L<k>_psi or L<k>_len")
        i, kind = int(m.group(1)) - 1, m.group(2)
        links.append(i)
        kinds.append(kind)
        labels.append(f"{_SYMBOL[kind]}{i + 1} {mech.names[i]}")
    moment_rows = tuple(r for r, k in enumerate(kinds) if k != "len")
    force_rows = tuple(sorted((r for r, k in enumerate(kinds) if k == "len"), key=lambda r: links[r]))
    return JointBasis(tuple(pm.joint_names), tuple(labels), tuple(links), tuple(kinds), np.linalg.inv(G),
                      moment_rows, force_rows)


def joint_quantities(mech: Mechanism, tau: np.ndarray) -> np.ndarray:
    """``tau_joint = G^-T tau``: the joint moments and rod forces, ``(S, dof)`` in the rows of
    :attr:`JointBasis.names`, from generalised forces ``(S, dof)`` of the absolute angles."""
    with np.errstate(invalid="ignore"):   # inf * 0 in a non-finite tau: NaN, reported by nonfinite_notes
        return np.asarray(tau, dtype=float) @ joint_basis(mech).G_inv


def moments_and_forces(mech: Mechanism, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The joint moments ``(S, revolute joints)`` (N·m) and rod forces ``(S, n)`` (N) of ``tau``."""
    jb = joint_basis(mech)
    tj = joint_quantities(mech, tau)
    return tj[:, list(jb.moment_rows)], tj[:, list(jb.force_rows)]


def moment_labels(mech: Mechanism) -> list[str]:
    jb = joint_basis(mech)
    return [jb.labels[r] for r in jb.moment_rows]


def force_labels(mech: Mechanism) -> list[str]:
    jb = joint_basis(mech)
    return [jb.labels[r] for r in jb.force_rows]


def generalised_moment_labels(mech: Mechanism) -> list[str]:
    """Labels of the paper's generalised moments (the angle rows of ``tau``), e.g. ``Mφ1 (abs.) stance_shin``."""
    n = mech.nlinks
    kinds = ["Mφ", "Mψ"] if mech.dim == 3 else ["Mφ"]
    return [f"{k}{i + 1} (abs.) {mech.names[i]}" for k in kinds for i in range(n)]


def generalised_moments(mech: Mechanism, tau: np.ndarray) -> np.ndarray:
    """The angle rows ``[M_phi..., M_psi...]`` of the paper's generalised forces, ``(S, (dim-1) n)``."""
    return np.asarray(tau, dtype=float)[:, : (mech.dim - 1) * mech.nlinks]


# ----------------------------------------------------------------------------- grouping by scale
@dataclass(frozen=True)
class ScaleGroups:
    """Curves grouped by the scale of their absolute maxima, as in the paper's Figs. 7 and 8."""

    groups: tuple[tuple[int, ...], ...]  # curve indices per panel, largest scale first, each by decreasing max
    zero: tuple[int, ...]                 # curves that are zero (max below ZERO_FRACTION of the largest)
    maxima: np.ndarray                    # max |value| of every curve


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
    bad = [f"{m}: skipped ({r.skipped})" if r.skipped else f"{m}: failed ({r.error})"
           for m, r in study.results.items() if not r.ok]
    return "; ".join(bad)


def nonfinite_notes(study: Study) -> list[str]:
    """One warning per method whose tau holds NaN or infinite values (they cannot be drawn)."""
    out = []
    for m in study.ok_methods():
        bad = ~np.isfinite(study.results[m].tau)
        if bad.any():
            rows = np.flatnonzero(bad.any(axis=1))
            out.append(f"WARNING: {m} returned {int(bad.sum())} non-finite value(s) at {rows.size} instant(s), "
                       f"first at t = {study.motion.t[rows[0]]:.4g} s; they are not drawn")
    return out


def _style_of(ok: list[str], ref: str | None, m: str):
    others = [x for x in ok if x != ref]
    return "-" if m == ref else _STYLES[others.index(m) % len(_STYLES)]


def _style_name(ok, ref, m) -> str:
    st = _style_of(ok, ref, m)
    return {"--": "dashed", ":": "dotted", "-.": "dash-dot"}.get(st, "patterned") if isinstance(st, str) else "patterned"


def _check_ok(study: Study) -> None:
    if not study.ok_methods():
        why = _not_run_line(study) or "no methods were run"
        raise ValueError(f"study {study.name!r}: no method produced tau ({why}); nothing to plot")


def _header(study: Study, what: str) -> str:
    mech = study.mechanism
    return f"{study.name} ({mech.dim}D, {mech.nlinks} links) — {study.motion_label}\n{what}"


# ----------------------------------------------------------------------------- Figs. 7 and 8
def _curves_figure(study: Study, kind: str, ratio: float = SCALE_RATIO) -> Figure:
    _check_ok(study)
    mech = study.mechanism
    ok = study.ok_methods()
    ref = reference_method(study)
    if kind == "moments":
        data = {m: moments_and_forces(mech, study.results[m].tau)[0] for m in ok}
        labels, unit, sym = moment_labels(mech), "N·m", "M"
        what = ("Control moments in the joints (the paper's Fig. 7): joint moments τ_joint = G⁻ᵀ τ\n"
                "about each joint's own angle (" + ("relative azimuth φ_k − φ_parent, absolute elevation ψ_k"
                                                    if mech.dim == 3 else "relative angle φ_k − φ_parent")
                + "), not the generalised forces of the absolute angles"
                + ("\n(Mψ of a link with children is its joint's moment minus its children's: net joint moments "
                   "are in the scene report)" if mech.dim == 3 else ""))
    else:
        data = {m: moments_and_forces(mech, study.results[m].tau)[1] for m in ok}
        labels, unit, sym = force_labels(mech), "N", "F"
        what = ("Longitudinal rod forces (the paper's Fig. 8): F_k along rod k\n"
                "(the same in joint and in absolute coordinates: l_k maps to itself)")
    t = study.motion.t
    # The reference's scales decide the panels; other methods overlay it. NaN are reported, not grouped.
    finite = np.where(np.isfinite(data[ref]), np.abs(data[ref]), 0.0)
    groups = group_by_scale(finite.max(axis=0), ratio)
    rows = max(len(groups.groups), 1)
    notes = [_methods_line(study) + f"; panels grouped by the scale of max |{sym}| (each spans at most {ratio:g}×)"]
    if groups.zero:
        notes.append(f"zero throughout (max |{sym}| < {ZERO_FRACTION:g} of the largest): "
                     + ", ".join(labels[j] for j in groups.zero))
    if _not_run_line(study):
        notes.append("not shown: " + _not_run_line(study))
    notes = _wrap_notes(notes + nonfinite_notes(study))
    fig = Figure(figsize=(11.5, 1.6 + 2.35 * rows + 0.2 * len(notes)), layout="constrained")
    axes, note_ax = _panels(fig, rows, len(notes))
    curve_color = curve_colors(mech, kind)
    for g, ax in enumerate(axes):
        idx = groups.groups[g] if groups.groups else ()
        for j in idx:
            for m in ok:
                ax.plot(t, data[m][:, j], color=curve_color[j], ls=_style_of(ok, ref, m),
                        lw=1.8 if m == ref else 1.2, label=labels[j] if m == ref else None, gid=f"{m}:{labels[j]}")
        ax.set_ylabel(f"{sym} ({unit})", fontsize=TEXT_PT)
        ax.set_title(scale_caption(groups, g, unit, sym) if groups.groups else "all zero", loc="left",
                     fontsize=TEXT_PT)
        ax.grid(True, alpha=0.3)
        ax.axhline(0.0, color="k", lw=0.6, alpha=0.5)
        ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=TEXT_PT, frameon=False)
        ax.set_xlim(t[0], t[-1])
        ax.tick_params(labelsize=TEXT_PT)
    axes[-1].set_xlabel("time t (s)", fontsize=TEXT_PT)
    if len(ok) > 1:   # line style = method, outside the plots
        handles = [Line2D([], [], color="0.3", ls=_style_of(ok, ref, m)) for m in ok]
        fig.legend(handles, ok, loc="outside right lower", fontsize=TEXT_PT, title="method (line style)",
                   title_fontsize=TEXT_PT, frameon=False)
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
    txt = ax.text(0.0, 1.0, "\n".join(lines), transform=ax.transAxes, ha="left", va="top", fontsize=TEXT_PT,
                  color="0.2")
    txt.set_in_layout(False)


def curve_colors(mech: Mechanism, kind: str) -> list[str]:
    """Colour of each curve of ``kind`` ("moments" or "forces"): a link's colour for its azimuth
    joint and rod force, the palette entry half-way round for its elevation joint (3D)."""
    jb = joint_basis(mech)
    rows = jb.moment_rows if kind == "moments" else jb.force_rows
    return [link_color(jb.link[r] + (len(_COLORS) // 2 if jb.kind[r] == "psi" else 0)) for r in rows]


def moments_figure(study: Study, ratio: float = SCALE_RATIO) -> Figure:
    """The joint moments along the motion (the paper's Fig. 7), panels grouped by scale."""
    return _curves_figure(study, "moments", ratio)


def forces_figure(study: Study, ratio: float = SCALE_RATIO) -> Figure:
    """The longitudinal rod forces along the motion (the paper's Fig. 8), panels grouped by scale."""
    return _curves_figure(study, "forces", ratio)


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
    notes = [f"reference: {ref}; one colour per method (legend); log scale: an instant where a method equals "
             f"{ref} exactly (Δ = 0) leaves a gap"] + (["not shown: " + _not_run_line(study)]
                                                       if _not_run_line(study) else [])
    notes = _wrap_notes(notes + nonfinite_notes(study))
    fig = Figure(figsize=(11.5, 5.6 + 0.2 * len(notes)), layout="constrained")
    axes, note_ax = _panels(fig, 2, len(notes))
    for ax, part, unit in ((axes[0], 0, "N·m"), (axes[1], 1, "N")):
        for k, m in enumerate(others):
            d = np.abs(moments_and_forces(mech, study.results[m].tau - study.results[ref].tau)[part]).max(axis=1)
            dmax = float(np.nanmax(d)) if np.isfinite(d).any() else float("nan")
            scale = float(np.nanmax(np.abs(moments_and_forces(mech, study.results[ref].tau)[part]))) or 1.0
            color = method_color(m, ok)
            if dmax == 0.0:
                ax.plot([], [], color=color, label=f"{m} − {ref}: identical (0)")
                continue
            ax.semilogy(t, np.where(d > 0, d, np.nan), color=color, lw=1.2, gid=f"diff:{m}",
                        label=f"{m} − {ref}: max {dmax:.2g} {unit}\n({dmax / scale:.1e} of the largest {ref} value)")
        name = "joint moments ΔM" if part == 0 else "rod forces ΔF"
        ax.set_ylabel(f"max |Δ| ({unit})", fontsize=TEXT_PT)
        ax.set_title(f"{name}: largest |method − {ref}| over the joints", loc="left", fontsize=TEXT_PT)
        ax.grid(True, which="both", alpha=0.3)
        ax.tick_params(labelsize=TEXT_PT)
        ax.legend(fontsize=TEXT_PT, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    axes[-1].set_xlabel("time t (s)", fontsize=TEXT_PT)
    axes[-1].set_xlim(t[0], t[-1])
    fig.suptitle(_header(study, f"Differences between methods, method − {ref}, in the joint moments τ_joint = G⁻ᵀ τ "
                                "and rod forces"), fontsize=TITLE_PT)
    _write_notes(note_ax, notes)
    return fig


# ----------------------------------------------------------------------------- kinogram (Fig. 9)
#: Marker area (pt^2) of the heaviest point mass in a kinogram.
KINOGRAM_MAX_AREA = 160.0
#: Opacity of the first frame of the overlay; the last is opaque.
KINOGRAM_FIRST_ALPHA = 0.15


@dataclass(frozen=True)
class Projection:
    """A view of the motion: which world axes are drawn, horizontal and vertical, and their names."""

    name: str
    short: str
    axes: tuple[int, int]
    labels: tuple[str, str]


def kinogram_frames(study: Study, frames: int) -> np.ndarray:
    """Sample indices of the kinogram's frames, evenly spread over the motion."""
    S = study.motion.t.shape[0]
    if frames < 1:
        raise ValueError(f"kinogram: field 'frames': expected >= 1, got {frames}")
    return np.unique(np.linspace(0, S - 1, min(frames, S)).round().astype(int))


def projections(mech: Mechanism) -> list[Projection]:
    """x-y for a planar model; sagittal x-z and frontal y-z for 3D. Axis names say only what the
    coordinates are (no "walking direction": a user's mechanism need not walk)."""
    if mech.dim == 2:
        return [Projection("plane of the model (x–y)", "x–y plane", (0, 1), ("x (m)", "y (m), up"))]
    return [Projection("sagittal projection (x–z)", "sagittal (x–z)", (0, 2), ("x (m)", "z (m), up")),
            Projection("frontal projection (y–z)", "frontal (y–z)", (1, 2), ("y (m)", "z (m), up"))]


def _draw_frame(ax, mech: Mechanism, P: np.ndarray, proj: Projection, area: np.ndarray, alpha: float, gid: str):
    """One frame in place: rods from start to end, point masses with area ∝ mass."""
    hx, vx = proj.axes
    for i in range(mech.nlinks):
        ax.plot([P[i, 0, hx], P[i, 2, hx]], [P[i, 0, vx], P[i, 2, vx]], color=link_color(i), lw=2.2, alpha=alpha,
                solid_capstyle="round", zorder=2, gid=f"rod:{gid}:{i}")
    ax.scatter(P[:, :, hx].ravel(), P[:, :, vx].ravel(), s=area.ravel(),
               c=[link_color(i) for i in range(mech.nlinks) for _ in range(3)], edgecolors="k", linewidths=0.5,
               alpha=alpha, zorder=3, gid=f"masses:{gid}")


def ground_label(mech: Mechanism) -> str:
    """What the dashed line at height 0 is: the floor for a model that stands on a stance leg (the
    exoskeleton's ``stance_shin`` starts at O), only the level of O for any other mechanism (a
    reversed link may reach below it: it is no floor)."""
    return "floor (height 0)" if "stance_shin" in mech.names else "height 0 (level of O; not a floor)"


def _floor_and_support(ax, proj: Projection, lo: float, hi: float) -> None:
    ax.plot([lo, hi], [0.0, 0.0], color="0.45", lw=1.0, ls="--", zorder=1, gid="floor")
    ax.plot([0.0], [0.0], marker="^", color="k", ms=8, ls="none", zorder=4, gid="support")


def kinogram_figure(study: Study, frames: int = 9) -> Figure:
    """Stick-figure frames of the motion (the paper's Fig. 9), drawn as they are.

    Every frame is drawn **in place**: the support point O stays at the origin and no frame is
    shifted. The top row overlays all frames in each projection (x-z and y-z for 3D, the model's
    plane for 2D), the later the more opaque; the bottom row shows the same frames one per panel,
    left to right in time, all at the same scale. Rods are lines from the start to the end of each
    link; point masses are dots whose area is proportional to their mass; a grey dashed line is
    height 0 through O (:func:`ground_label`: the floor only for a model standing on a stance leg)."""
    mech = study.mechanism
    idx = kinogram_frames(study, frames)
    P = point_mass_positions(mech, study.motion.q[idx])          # (F, n, 3, dim)
    F = len(idx)
    projs = projections(mech)
    masses = mech.mass_array
    area = masses / masses.max() * KINOGRAM_MAX_AREA
    t = study.motion.t[idx]
    alphas = np.linspace(KINOGRAM_FIRST_ALPHA, 1.0, F) if F > 1 else np.ones(1)
    lo = {a: float(min(P[..., a].min(), 0.0)) - 0.08 for a in range(mech.dim)}
    hi = {a: float(max(P[..., a].max(), 0.0)) + 0.08 for a in range(mech.dim)}
    span = lambda a: hi[a] - lo[a]
    vert = projs[0].axes[1]
    cell = max(span(projs[0].axes[0]), 0.3)
    small = min(1.6, 14.0 / (F * cell))                  # inches per metre in the frame panels
    width = max(F * cell * small + 1.5, 11.0)
    inch = min(4.4, 0.6 * width / sum(span(p.axes[0]) for p in projs))   # inches per metre in the overlay
    fig = Figure(figsize=(width, span(vert) * (inch + small) + 3.4), layout="constrained")
    top, bottom = fig.subfigures(2, 1, height_ratios=[span(vert) * inch + 1.3, span(vert) * small + 1.4])
    ratios = [span(p.axes[0]) for p in projs]
    grid = top.subplots(1, len(projs) + 1, squeeze=False,
                        gridspec_kw={"width_ratios": ratios + [max(0.25 * sum(ratios), width / inch - sum(ratios))]})[0]
    overlay, note = grid[:-1], grid[-1]
    for ax, proj in zip(overlay, projs):
        hx, vx = proj.axes
        for k in range(F):
            _draw_frame(ax, mech, P[k], proj, area, float(alphas[k]), f"overlay:{proj.name}:{k}")
        _floor_and_support(ax, proj, lo[hx], hi[hx])
        ax.set_xlim(lo[hx], hi[hx])
        ax.set_ylim(lo[vx], hi[vx])
        ax.set_aspect("equal")
        ax.set_xlabel(proj.labels[0], fontsize=TEXT_PT)
        ax.set_ylabel(proj.labels[1], fontsize=TEXT_PT)
        ax.set_title(proj.short, loc="left", fontsize=TEXT_PT)
        ax.tick_params(labelsize=TEXT_PT)
        ax.locator_params(axis="x", nbins=4)
    note.set_axis_off()
    how = [f"How to read: every frame is drawn where it is. The support point O (▲) stays at the origin and no "
           f"frame is shifted, so the model does not walk away: link 1 stays on O for the whole motion.",
           "", f"Left: all {F} frames overlaid in each projection; the first frame is the palest "
           f"(opacity {KINOGRAM_FIRST_ALPHA:g}), the last is opaque.",
           "", "Below: the same frames one per panel, left to right in time, at one common scale.",
           "", "Rods run from the start to the end of each link; the dots are the point masses, area ∝ mass; "
           f"the grey dashed line: {ground_label(mech)}."]
    # wrapped to the note's column by hand: the text takes no part in the layout (constrained layout
    # would otherwise shrink the plots beside it to make room for a long line)
    chars = max(30, int((width - inch * sum(ratios) - 1.0) * 72 / (0.6 * TEXT_PT)))
    text = "\n".join("\n".join(textwrap.wrap(line, chars)) if line else "" for line in how)
    note.text(0.06, 0.95, text, transform=note.transAxes, ha="left", va="top", fontsize=TEXT_PT,
              color="0.15").set_in_layout(False)
    panels = bottom.subplots(1, F, sharey=True, squeeze=False)[0]
    proj = projs[0]
    hx, vx = proj.axes
    for k, ax in enumerate(panels):
        _draw_frame(ax, mech, P[k], proj, area, 1.0, f"frame:{k}")
        _floor_and_support(ax, proj, lo[hx], hi[hx])
        ax.set_xlim(lo[hx], hi[hx])
        ax.set_ylim(lo[vx], hi[vx])
        ax.set_aspect("equal")
        ax.set_title(f"frame {k + 1}\nt = {t[k]:.2f} s", fontsize=TEXT_PT)
        ax.set_xlabel(proj.labels[0].split(",")[0], fontsize=TEXT_PT)
        ax.tick_params(labelsize=TEXT_PT)
        ax.locator_params(axis="x", nbins=3)
    panels[0].set_ylabel(proj.labels[1], fontsize=TEXT_PT)
    bottom.suptitle(f"The same {F} frames one per panel, {proj.name}, left to right in time", fontsize=TEXT_PT,
                    x=0.01, ha="left")
    handles = [Line2D([], [], color=link_color(i), lw=2.2, label=f"link {i + 1}: {mech.names[i]}")
               for i in range(mech.nlinks)]
    handles += [Line2D([], [], color="0.45", ls="--", label=ground_label(mech)),
                Line2D([], [], color="k", marker="^", ls="none", label="support point O")]
    fig.legend(handles=handles, fontsize=TEXT_PT, loc="outside lower center", ncols=min(len(handles), 7), frameon=False)
    fig.suptitle(_header(study, f"Kinogram (paper's Fig. 9): {F} frames over {t[-1] - t[0]:.2f} s, drawn in place "
                                f"(the support point O is fixed; frames are not shifted); dot area ∝ point mass "
                                f"(largest {masses.max():.3g} kg)"), fontsize=TITLE_PT)
    return fig


# ----------------------------------------------------------------------------- overview picture
def overview_figure(study: Study, frame: float = 0.3) -> Figure:
    """One picture of a scene laid out like its rerun recording: the model in 3D at one instant
    (rods, point masses sized by mass, trails of the last 0.2 s) on the left; joint moments,
    rod forces and the differences between methods on the right."""
    from matplotlib.ticker import MaxNLocator

    _check_ok(study)

    mech, t = study.mechanism, study.motion.t
    ok, ref = study.ok_methods(), reference_method(study)
    fig = Figure(figsize=(16, 9), layout="constrained")
    fig.get_layout_engine().set(w_pad=0.15, wspace=0.12)   # room for the 3D panel's z label
    gs = fig.add_gridspec(3, 2, width_ratios=[1.25, 1.45])
    ax3 = fig.add_subplot(gs[:, 0], projection="3d")
    s = int(round(frame * (len(t) - 1)))
    P = point_mass_positions(mech, study.motion.q)
    P3 = P if mech.dim == 3 else np.stack([P[..., 0], np.zeros_like(P[..., 0]), P[..., 1]], axis=-1)
    masses = mech.mass_array
    handles = []
    for i in range(mech.nlinks):
        a, b = P3[s, i, 0], P3[s, i, 2]
        handles += ax3.plot([a[0], b[0]], [a[1], b[1]], [a[2], b[2]], color=link_color(i), lw=3,
                            label=f"link {i + 1}: {mech.names[i]}")
        ax3.scatter(P3[s, i, :, 0], P3[s, i, :, 1], P3[s, i, :, 2], s=masses[i] / masses.max() * 220,
                    color=link_color(i), edgecolors="k", depthshade=False)
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    back = max(int(round(0.2 / dt)), 1)
    for k, (name, (link, beta)) in enumerate(trail_points(mech).items()):
        w = P3[max(s - back, 0): s + 1, link, beta]
        handles += ax3.plot(w[:, 0], w[:, 1], w[:, 2], color="k", lw=1.2, ls=("--", ":", "-.")[k % 3],
                            label=f"trail: {name}, last 0.2 s")
    handles += [ax3.scatter([0], [0], [0], marker="^", color="k", s=60, label="support point O")]
    span = float(np.ptp(P3[..., 2])) or 1.0
    c = P3[s].reshape(-1, 3).mean(axis=0)
    ax3.set_xlim(c[0] - span / 2, c[0] + span / 2)
    ax3.set_ylim(c[1] - span / 2, c[1] + span / 2)
    ax3.set_zlim(min(0.0, P3[..., 2].min()), P3[..., 2].max())
    ax3.set_box_aspect((1, 1, 1), zoom=1.1)
    for axis in (ax3.xaxis, ax3.yaxis, ax3.zaxis):
        axis.set_major_locator(MaxNLocator(4))
    ax3.tick_params(labelsize=TEXT_PT)
    ax3.set_xlabel("x (m)", fontsize=TEXT_PT, labelpad=6)
    ax3.set_ylabel("y (m)", fontsize=TEXT_PT, labelpad=6)
    ax3.set_zlabel("z (m), up", fontsize=TEXT_PT, labelpad=6)
    ax3.view_init(elev=12, azim=-60)
    ax3.set_title(f"3D view at t = {t[s]:.2f} s; dot area ∝ point mass", fontsize=TEXT_PT)
    fig.legend(handles=handles, loc="outside lower left", fontsize=TEXT_PT, ncols=3, frameon=False)
    M = moments_and_forces(mech, study.results[ref].tau)
    for r, (vals, labels, unit, sym, title) in enumerate(
            ((M[0], moment_labels(mech), "N·m", "M", "joint moments τ_joint = G⁻ᵀ τ"),
             (M[1], force_labels(mech), "N", "F", "rod forces F"))):
        ax = fig.add_subplot(gs[r, 1])
        inv = curve_colors(mech, "moments" if r == 0 else "forces")
        for j in range(vals.shape[1]):
            ax.plot(t, vals[:, j], color=inv[j], lw=1.3, label=labels[j])
        ax.set_ylabel(f"{sym} ({unit})", fontsize=TEXT_PT)
        ax.set_title(f"{title} ({ref})", loc="left", fontsize=TEXT_PT)
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=TEXT_PT)
        ax.legend(fontsize=TEXT_PT, ncols=2 if vals.shape[1] > 6 else 1, loc="center left", bbox_to_anchor=(1.0, 0.5),
                  frameon=False)
        ax.set_xlim(t[0], t[-1])
        ax.tick_params(labelbottom=False)
    ax = fig.add_subplot(gs[2, 1])
    others = [m for m in ok if m != ref]
    for m in others:
        tj = joint_quantities(mech, study.results[m].tau - study.results[ref].tau)
        d = np.abs(tj).max(axis=1)
        ax.semilogy(t, np.where(d > 0, d, np.nan), color=method_color(m, ok), label=f"{m} − {ref}", gid=f"diff:{m}")
    ax.set_title("differences: largest |method − reference| over all joints"
                 if others else "differences: only one method ran", loc="left", fontsize=TEXT_PT)
    ax.set_ylabel("max |Δ| (N·m or N)", fontsize=TEXT_PT)
    if others:
        ax.legend(fontsize=TEXT_PT, loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False)
    ax.grid(True, which="both", alpha=0.3)
    ax.tick_params(labelsize=TEXT_PT)
    ax.set_xlabel("time t (s)", fontsize=TEXT_PT)
    ax.set_xlim(t[0], t[-1])
    what = f"Overview in the layout of the rerun recording: moments and forces of {ref}" + (
        f"; differences of {', '.join(others)} from it" if others else "")
    fig.suptitle(_header(study, what), fontsize=TITLE_PT)
    return fig


# ----------------------------------------------------------------------------- saving
#: Anatomical names of link ends, for the exoskeleton's link names only.
_ANATOMY = {"stance_thigh": "hip", "swing_shin": "swing ankle", "stance_shin": "stance knee", "swing_thigh": "swing knee"}


def trail_points(mech: Mechanism) -> dict[str, tuple[int, int]]:
    """The points whose recent path is drawn, as ``name -> (link, mass index)``, named after the
    mechanism's own links: ``"<link> end"``, with the anatomical name in brackets for the
    exoskeleton's links (``"stance_thigh end (hip)"``).

    Which points: the branch point where reversed (hanging) links start, i.e. the end of the parent
    of the first reversed link, and the free end of every reversed leaf link; a model without
    reversed links gets the free end of its last link, its tip (``"tip (hand end)"`` for a user's
    arm whose last link is ``hand``).
    """
    def name(i: int) -> str:
        n = mech.names[i]
        return f"{n} end" + (f" ({_ANATOMY[n]})" if n in _ANATOMY else "")

    out: dict[str, tuple[int, int]] = {}
    reversed_links = [i for i in range(mech.nlinks) if mech.sign[i] < 0]
    for i in reversed_links:
        p = mech.parent[i]
        if p >= 0 and mech.sign[p] > 0:
            out[name(p)] = (p, 2)
            break
    for i in reversed_links:
        if not mech.children[i]:
            out[name(i)] = (i, 2)
    if not reversed_links:
        last = mech.nlinks - 1
        n = mech.names[last]
        out[f"{n} end ({_ANATOMY[n]})" if n in _ANATOMY else f"tip ({n} end)"] = (last, 2)
    return out


#: The scene figures, by output name.
FIGURES = ("moments", "forces", "kinogram", "differences", "overview")


def scene_figure(study: Study, kind: str) -> Figure | None:
    """The figure ``kind`` (one of :data:`FIGURES`) of a study; None for differences with fewer than
    two methods."""
    make = {"moments": moments_figure, "forces": forces_figure, "kinogram": kinogram_figure,
            "differences": differences_figure, "overview": overview_figure}
    if kind not in make:
        raise ValueError(f"scene figure: field 'kind': expected one of {', '.join(FIGURES)}, got {kind!r}")
    return make[kind](study)


def write_plots(study: Study, out_dir: str | Path, prefix: str | None = None, frames: int = 9) -> list[Path]:
    """Write ``<prefix>-moments.png``, ``-forces.png``, ``-kinogram.png`` and, with two or more
    methods, ``-differences.png``; return the paths written."""
    out = Path(out_dir)
    prefix = prefix or study.name
    paths = [save_figure(moments_figure(study), out / f"{prefix}-moments.png"),
             save_figure(forces_figure(study), out / f"{prefix}-forces.png"),
             save_figure(kinogram_figure(study, frames), out / f"{prefix}-kinogram.png")]
    diff = differences_figure(study)
    if diff is not None:
        paths.append(save_figure(diff, out / f"{prefix}-differences.png"))
    return paths


__all__ = [
    "FIGURES", "JointBasis", "METHOD_COLORS", "Projection", "ScaleGroups", "TEXT_PT", "curve_colors",
    "differences_figure", "force_labels", "forces_figure", "generalised_moment_labels", "generalised_moments",
    "ground_label", "group_by_scale", "joint_basis", "joint_quantities", "kinogram_figure", "kinogram_frames", "link_color",
    "method_color", "moment_labels", "moments_and_forces", "moments_figure", "nonfinite_notes", "overview_figure",
    "projections", "reference_method", "save_figure", "scene_figure", "trail_points", "write_plots",
]
