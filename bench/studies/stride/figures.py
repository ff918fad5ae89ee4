"""The stride's figures: its curves against Winter's over the cycle, and its kinogram.

Every panel draws our curve and Winter's (:mod:`.comparison`), with units and the sign convention in the
axis label and the panel's r and RMS error in its title; the legend sits below all panels (a figure
legend, outside every axes), and the layout is constrained so no title is cut off.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT, link_color
from exo_bench.bench.studies.stride.comparison import BINS, Comparison
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.normative import SHORT_SOURCE

#: Panel order (rows of three) and each quantity's axis label (unit and sign convention).
PANELS = (
    ("hip moment", "hip moment (N·m/kg)\non thigh, ccw +"),
    ("knee moment", "knee moment (N·m/kg)\non leg, ccw +"),
    ("ankle moment", "ankle moment (N·m/kg)\non foot, ccw +"),
    ("hip power", "hip power (W/kg)\ngenerated +"),
    ("knee power", "knee power (W/kg)\ngenerated +"),
    ("ankle power", "ankle power (W/kg)\ngenerated +"),
    ("vertical GRF", "vertical GRF, right foot\n(body weights), up +"),
    ("fore-aft GRF", "fore-aft GRF, right foot\n(body weights), forward +"),
    ("hat angle", "HAT angle (deg)\nhip→head, ccw from +x"),
    ("thigh angle", "thigh angle (deg)\nknee→hip, ccw from +x"),
    ("leg angle", "leg angle (deg)\nankle→knee, ccw from +x"),
    ("foot angle", "foot angle (deg)\ntoe→ankle, ccw from +x"),
)
OURS, WINTERS = "#1f77b4", "0.15"
#: Frames drawn in the kinogram.
KINOGRAM_FRAMES = 11


def winter_figure(c: Comparison, what: str) -> Figure:
    """Our curves against Winter's, one panel per quantity of :data:`PANELS` (``what``: the stride, for
    the title)."""
    pct = (np.arange(BINS) + 0.5) * 100.0 / BINS
    rows = (len(PANELS) + 2) // 3
    fig = Figure(figsize=(13.0, 3.0 * rows + 1.6), layout="constrained")
    axes = fig.subplots(rows, 3, squeeze=False)
    for ax, (key, label) in zip(axes.flat, PANELS, strict=False):
        cv = c.curves[key]
        ax.plot(pct, cv.ours, color=OURS, lw=1.8, gid=f"ours:{key}")
        ax.plot(pct, cv.winter, color=WINTERS, lw=1.4, ls="--", gid=f"winter:{key}")
        ax.axvline(c.stance[0], color=OURS, lw=0.8, ls=":")
        ax.axvline(c.stance[1], color=WINTERS, lw=0.8, ls=":")
        ax.set_title(
            f"r = {cv.r:.2f}, RMS error {cv.rms_error:.3g} (Winter's RMS {cv.winter_rms:.3g})", fontsize=TEXT_PT
        )
        ax.set_ylabel(label, fontsize=TEXT_PT)
        ax.set_xlabel("% of gait cycle (right heel strike = 0)", fontsize=TEXT_PT)
        ax.set_xlim(0, 100)
        ax.tick_params(labelsize=TEXT_PT)
        ax.grid(True, lw=0.3, alpha=0.5)
    for ax in list(axes.flat)[len(PANELS) :]:
        ax.set_axis_off()
    handles = [
        Line2D([], [], color=OURS, lw=1.8, label="this stride"),
        Line2D([], [], color=WINTERS, lw=1.4, ls="--", label=f"Winter's stride ({SHORT_SOURCE}, one subject)"),
        Line2D([], [], color=OURS, lw=0.8, ls=":", label=f"our toe-off ({c.stance[0]:.1f} %)"),
        Line2D([], [], color=WINTERS, lw=0.8, ls=":", label=f"Winter's toe-off ({c.stance[1]:.1f} %)"),
    ]
    fig.legend(handles=handles, fontsize=TEXT_PT, loc="outside lower center", ncols=4, frameon=False)
    fig.suptitle(
        f"{what}\nagainst Winter's stride over the gait cycle: 1 % bin means, both cut at the right heel strike",
        fontsize=TITLE_PT,
    )
    return fig


def stride_kinogram(mech: Mechanism, t: np.ndarray, q: np.ndarray, what: str, frames: int = KINOGRAM_FRAMES) -> Figure:
    """The stride drawn where it walks (O fixed, the root rod carries the hips forward): ``frames``
    evenly spread frames, the hip's path, and the floor."""
    P = point_mass_positions(mech, q)  # (K, n, 3, 2)
    idx = np.unique(np.linspace(0, len(t) - 1, frames).round().astype(int))
    root = mech.names.index("root")
    links = [i for i in range(mech.nlinks) if i != root]
    lo, hi = float(P[:, links, :, 0].min()) - 0.1, float(P[:, links, :, 0].max()) + 0.1
    top = float(P[:, links, :, 1].max()) + 0.1
    width = min(22.0, max(10.0, 6.0 * (hi - lo)))
    fig = Figure(figsize=(width, width * (top + 0.15) / (hi - lo) + 1.8), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    ax.plot([lo, hi], [0, 0], color="0.45", lw=1.0, ls="--", zorder=1, gid="floor")
    ax.plot(P[:, root, 2, 0], P[:, root, 2, 1], color="k", lw=1.0, ls=":", zorder=1, gid="hip-path")
    m = mech.mass_array
    area = m / m.max() * 100.0
    for k, s in enumerate(idx):
        alpha = 0.35 + 0.65 * k / max(1, len(idx) - 1)
        for i in links:
            c = link_color(i)
            ax.plot(P[s, i, [0, 2], 0], P[s, i, [0, 2], 1], color=c, lw=2.0, alpha=alpha, zorder=2, gid=f"rod:{s}:{i}")
            ax.scatter(P[s, i, :, 0], P[s, i, :, 1], s=area[i], c=[c] * 3, edgecolors="k", linewidths=0.3, zorder=3)
    ax.set_xlim(lo, hi)
    ax.set_ylim(-0.05, top)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m), walking direction", fontsize=TEXT_PT)
    ax.set_ylabel("y (m), up", fontsize=TEXT_PT)
    ax.tick_params(labelsize=TEXT_PT)
    handles = [Line2D([], [], color=link_color(i), lw=2, label=mech.names[i].replace("_", " ")) for i in links]
    handles += [
        Line2D([], [], color="k", ls=":", label="hip path"),
        Line2D([], [], color="0.45", ls="--", label="floor"),
    ]
    fig.legend(handles=handles, fontsize=TEXT_PT, loc="outside lower center", ncols=6, frameon=False)
    fig.suptitle(
        f"{what}\nkinogram: {len(idx)} frames over {t[-1] - t[0]:.3f} s (later frames darker); dot area ∝ point mass",
        fontsize=TITLE_PT,
    )
    return fig


__all__ = ["KINOGRAM_FRAMES", "PANELS", "stride_kinogram", "winter_figure"]
