"""A scene's figures (:data:`FIGURES`, :func:`scene_figure`, :func:`write_plots`) and the stick figures of
its motion: the kinogram (the paper's Fig. 9), the overview picture of a scene, and the points whose
trails a recording draws.

* :func:`exo_bench.bench.output.figures.curves.moments_figure` - the net joint moments (Fig. 7), the
  numbers of the scene report,
* :func:`exo_bench.bench.output.figures.curves.forces_figure` - the longitudinal forces along the rods (Fig. 8),
* :func:`kinogram_figure` - stick-figure frames of the motion (Fig. 9),
* :func:`exo_bench.bench.output.figures.curves.differences_figure` - every method minus the reference,
* :func:`overview_figure` - one picture of a scene (kinogram, moments, forces, differences).

**Which moments.** A study's ``tau`` are the generalised forces of the paper's *absolute*
angles (eq. 4 has ``M1 - M2`` on ``phi_1``). The moments figure shows the NET joint moments (the
moment the parent side exerts on everything beyond a joint, about it: :func:`exo_bench.bench.output.figures.curves.moments_figure`), the
numbers of the scene report's Plausibility table. The differences compare the methods in the joint
coordinates, ``tau_joint = G^-T tau`` with ``G`` the constant map ``q_joint = G q`` of
:func:`exo_bench.models.engines.pinocchio_backend.build_model`, whose elevation rows of a link with children
are its joint's moment minus its children's. The rod forces ``F_k`` are the same in both sets,
because the column of ``G`` of ``l_k`` is a unit vector, so ``F_k = tau_joint[len_k] = tau[l_k]``.
Every figure says in its title which it shows, with units and sign conventions.

Figures are built with matplotlib's object API (no pyplot, no global backend switch) and are
saved atomically by :func:`exo_bench.bench.output.provenance.save_figure`.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.lines import Line2D

from exo_bench.bench.output.figures.curves import (
    _check_ok,
    _header,
    curve_colors,
    differences_figure,
    draw_net_moments,
    forces_figure,
    moments_figure,
    net_moment_curves,
)
from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT, link_color, method_color
from exo_bench.bench.output.provenance import save_figure
from exo_bench.models.engines.joint_coordinates import force_labels, joint_quantities, moments_and_forces
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.mechanism.mechanism import Mechanism

if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study


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
    return [
        Projection("sagittal projection (x–z)", "sagittal (x–z)", (0, 2), ("x (m)", "z (m), up")),
        Projection("frontal projection (y–z)", "frontal (y–z)", (1, 2), ("y (m)", "z (m), up")),
    ]


def _draw_frame(ax, mech: Mechanism, P: np.ndarray, proj: Projection, area: np.ndarray, alpha: float, gid: str):
    """One frame in place: rods from start to end, point masses with area ∝ mass."""
    hx, vx = proj.axes
    for i in range(mech.nlinks):
        ax.plot(
            [P[i, 0, hx], P[i, 2, hx]],
            [P[i, 0, vx], P[i, 2, vx]],
            color=link_color(i),
            lw=2.2,
            alpha=alpha,
            solid_capstyle="round",
            zorder=2,
            gid=f"rod:{gid}:{i}",
        )
    ax.scatter(
        P[:, :, hx].ravel(),
        P[:, :, vx].ravel(),
        s=area.ravel(),
        c=[link_color(i) for i in range(mech.nlinks) for _ in range(3)],
        edgecolors="k",
        linewidths=0.5,
        alpha=alpha,
        zorder=3,
        gid=f"masses:{gid}",
    )


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
    P = point_mass_positions(mech, study.motion.q[idx])  # (F, n, 3, dim)
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
    small = min(1.6, 14.0 / (F * cell))  # inches per metre in the frame panels
    width = max(F * cell * small + 1.5, 11.0)
    inch = min(4.4, 0.6 * width / sum(span(p.axes[0]) for p in projs))  # inches per metre in the overlay
    fig = Figure(figsize=(width, span(vert) * (inch + small) + 3.4), layout="constrained")
    top, bottom = fig.subfigures(
        2, 1, squeeze=False, height_ratios=[span(vert) * inch + 1.3, span(vert) * small + 1.4]
    )[:, 0]
    ratios = [span(p.axes[0]) for p in projs]
    grid = top.subplots(
        1,
        len(projs) + 1,
        squeeze=False,
        gridspec_kw={"width_ratios": ratios + [max(0.25 * sum(ratios), width / inch - sum(ratios))]},
    )[0]
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
    how = [
        "How to read: every frame is drawn where it is. The support point O (▲) stays at the origin and no "
        "frame is shifted, so the model does not walk away: link 1 stays on O for the whole motion.",
        "",
        f"Left: all {F} frames overlaid in each projection; the first frame is the palest "
        f"(opacity {KINOGRAM_FIRST_ALPHA:g}), the last is opaque.",
        "",
        "Below: the same frames one per panel, left to right in time, at one common scale.",
        "",
        "Rods run from the start to the end of each link; the dots are the point masses, area ∝ mass; "
        f"the grey dashed line: {ground_label(mech)}.",
    ]
    # wrapped to the note's column by hand: the text takes no part in the layout (constrained layout
    # would otherwise shrink the plots beside it to make room for a long line)
    chars = max(30, int((width - inch * sum(ratios) - 1.0) * 72 / (0.6 * TEXT_PT)))
    text = "\n".join("\n".join(textwrap.wrap(line, chars)) if line else "" for line in how)
    note.text(
        0.06, 0.95, text, transform=note.transAxes, ha="left", va="top", fontsize=TEXT_PT, color="0.15"
    ).set_in_layout(False)
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
    bottom.suptitle(
        f"The same {F} frames one per panel, {proj.name}, left to right in time", fontsize=TEXT_PT, x=0.01, ha="left"
    )
    handles = [
        Line2D([], [], color=link_color(i), lw=2.2, label=f"link {i + 1}: {mech.names[i]}") for i in range(mech.nlinks)
    ]
    handles += [
        Line2D([], [], color="0.45", ls="--", label=ground_label(mech)),
        Line2D([], [], color="k", marker="^", ls="none", label="support point O"),
    ]
    fig.legend(handles=handles, fontsize=TEXT_PT, loc="outside lower center", ncols=min(len(handles), 7), frameon=False)
    fig.suptitle(
        _header(
            study,
            f"Kinogram (paper's Fig. 9): {F} frames over {t[-1] - t[0]:.2f} s, drawn in place "
            f"(the support point O is fixed; frames are not shifted); dot area ∝ point mass "
            f"(largest {masses.max():.3g} kg)",
        ),
        fontsize=TITLE_PT,
    )
    return fig


# ----------------------------------------------------------------------------- overview picture
def overview_figure(study: Study, frame: float = 0.3) -> Figure:
    """One picture of a scene laid out like its rerun recording: the model in 3D at one instant
    (rods, point masses sized by mass, trails of the last 0.2 s) on the left; joint moments,
    rod forces and the differences between methods on the right."""
    from matplotlib.ticker import MaxNLocator

    ref = _check_ok(study)

    mech, t = study.mechanism, study.motion.t
    ok = study.ok_methods()
    layout = ConstrainedLayoutEngine()
    fig = Figure(figsize=(16, 9), layout=layout)
    layout.set(w_pad=0.15, wspace=0.12)  # room for the 3D panel's z label
    gs = fig.add_gridspec(3, 2, width_ratios=[1.25, 1.45])
    ax3 = fig.add_subplot(gs[:, 0], projection="3d")
    s = int(round(frame * (len(t) - 1)))
    P = point_mass_positions(mech, study.motion.q)
    P3 = P if mech.dim == 3 else np.stack([P[..., 0], np.zeros_like(P[..., 0]), P[..., 1]], axis=-1)
    masses = mech.mass_array
    handles = []
    for i in range(mech.nlinks):
        a, b = P3[s, i, 0], P3[s, i, 2]
        handles += ax3.plot(
            [a[0], b[0]], [a[1], b[1]], [a[2], b[2]], color=link_color(i), lw=3, label=f"link {i + 1}: {mech.names[i]}"
        )
        ax3.scatter(
            P3[s, i, :, 0],
            P3[s, i, :, 1],
            P3[s, i, :, 2],
            s=masses[i] / masses.max() * 220,
            color=link_color(i),
            edgecolors="k",
            depthshade=False,
        )
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    back = max(int(round(0.2 / dt)), 1)
    for k, (name, (link, beta)) in enumerate(trail_points(mech).items()):
        w = P3[max(s - back, 0) : s + 1, link, beta]
        handles += ax3.plot(
            w[:, 0],
            w[:, 1],
            w[:, 2],
            color="k",
            lw=1.2,
            ls=("--", ":", "-.")[k % 3],
            label=f"trail: {name}, last 0.2 s",
        )
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
    sagittal = net_moment_curves(study)[0]  # the report's numbers (net joint moments, bench/output/figures/curves.py)
    ax = fig.add_subplot(gs[0, 1])
    draw_net_moments(ax, study, sagittal, [f"M{k + 1} {name}" for k, name in enumerate(mech.names)])
    ax.set_title(f"net joint moments, {ax.get_title(loc='left')}", loc="left", fontsize=TEXT_PT)
    ax.legend(fontsize=TEXT_PT, loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False)
    ax.tick_params(labelbottom=False)
    forces = moments_and_forces(mech, study.tau(ref))[1]
    ax = fig.add_subplot(gs[1, 1], sharex=ax)
    inv = curve_colors(mech, "forces")
    for j, label in enumerate(force_labels(mech)):
        ax.plot(t, forces[:, j], color=inv[j], lw=1.3, label=label)
    ax.set_ylabel("F (N)", fontsize=TEXT_PT)
    ax.set_title(f"rod forces F ({ref}; positive pushes the rod longer)", loc="left", fontsize=TEXT_PT)
    ax.grid(True, alpha=0.3)
    ax.tick_params(labelsize=TEXT_PT)
    ax.legend(fontsize=TEXT_PT, loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False)
    ax.set_xlim(t[0], t[-1])
    ax.tick_params(labelbottom=False)
    ax = fig.add_subplot(gs[2, 1])
    others = [m for m in ok if m != ref]
    for m in others:
        tj = joint_quantities(mech, study.tau(m) - study.tau(ref))
        d = np.abs(tj).max(axis=1)
        ax.semilogy(t, np.where(d > 0, d, np.nan), color=method_color(m, ok), label=f"{m} − {ref}", gid=f"diff:{m}")
    ax.set_title(
        "differences: largest |method − reference| over all joints" if others else "differences: only one method ran",
        loc="left",
        fontsize=TEXT_PT,
    )
    ax.set_ylabel("max |Δ| (N·m or N)", fontsize=TEXT_PT)  # of tau_joint = G^-T tau: no sign
    if others:
        ax.legend(fontsize=TEXT_PT, loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False)
    ax.grid(True, which="both", alpha=0.3)
    ax.tick_params(labelsize=TEXT_PT)
    ax.set_xlabel("time t (s)", fontsize=TEXT_PT)
    ax.set_xlim(t[0], t[-1])
    what = f"Overview in the layout of the rerun recording: net joint moments (N·m/kg), forces of {ref} (N)" + (
        f"; differences of {', '.join(others)} from it" if others else ""
    )
    fig.suptitle(_header(study, what), fontsize=TITLE_PT)
    return fig


# ----------------------------------------------------------------------------- saving
#: Anatomical names of link ends, for the exoskeleton's link names only.
_ANATOMY = {
    "stance_thigh": "hip",
    "swing_shin": "swing ankle",
    "stance_shin": "stance knee",
    "swing_thigh": "swing knee",
}


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


if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study


#: The scene figures, by output name.
FIGURES = ("moments", "forces", "kinogram", "differences", "overview")


def scene_figure(study: Study, kind: str) -> Figure | None:
    """The figure ``kind`` (one of :data:`FIGURES`) of a study; None for differences with fewer than
    two methods."""
    make = {
        "moments": moments_figure,
        "forces": forces_figure,
        "kinogram": kinogram_figure,
        "differences": differences_figure,
        "overview": overview_figure,
    }
    if kind not in make:
        raise ValueError(f"scene figure: field 'kind': expected one of {', '.join(FIGURES)}, got {kind!r}")
    return make[kind](study)


def write_plots(study: Study, out_dir: str | Path, prefix: str | None = None, frames: int = 9) -> list[Path]:
    """Write ``<prefix>-moments.png``, ``-forces.png``, ``-kinogram.png`` and, with two or more
    methods, ``-differences.png``; return the paths written."""
    out = Path(out_dir)
    prefix = prefix or study.name
    paths = [
        save_figure(moments_figure(study), out / f"{prefix}-moments.png"),
        save_figure(forces_figure(study), out / f"{prefix}-forces.png"),
        save_figure(kinogram_figure(study, frames), out / f"{prefix}-kinogram.png"),
    ]
    diff = differences_figure(study)
    if diff is not None:
        paths.append(save_figure(diff, out / f"{prefix}-differences.png"))
    return paths
