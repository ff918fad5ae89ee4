"""The scene motion ``kind = "stride"``: the stored full stride of the 2D human, run from its stored solution,
and its figures (its curves against Winter's over the cycle, and its kinogram).

In a scene file::

    mechanism = "human-2d"
    [motion]
    kind = "stride"        # the stored stride bench/studies/stride/data/<human-2d>-<variant>-v<cm/s>.npz
    variant = "human"      # "human" (leg rods held within 1 cm) or "exo" (rods free within their specs)
    speed = 1.41           # m/s: which stored stride

No solve runs: the stride is read (:func:`exo_bench.bench.studies.stride.data.load`, reused only for an
equal mechanism) and every method's inverse dynamics runs along its nodes. Beside the scene's usual
outputs the scene writes the comparison with Winter's curves (``<scene>-winter.png``,
:func:`extra_files`), its own kinogram (the stride walks from O: the root rod carries the hips), its
section of the report (:mod:`~exo_bench.bench.studies.stride.report`) and, in the recording, the actuators' loads and the ground force
over time (:func:`log_stride`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from exo_bench.bench.studies.stride import data
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.files import file_stem
from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT, link_color
from exo_bench.bench.studies.stride.comparison import Comparison
from exo_bench.bench.studies.stride.cycle import BINS
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.gait.normative import SHORT_SOURCE


#: The extra figure of a stride scene: our curves against Winter's.
WINTER_FIGURE = "winter"


def load_motion(path: Path, m: dict, mech: Mechanism) -> dict:
    """The ``[motion]`` table of a stride scene, checked: ``{"kind", "variant", "speed", "stored"}``."""
    variant, speed = m.get("variant", "human"), m.get("speed", 1.41)
    if not isinstance(variant, str) or variant not in data.VARIANTS:
        raise ValueError(f"{path}: field 'motion.variant': expected one of {', '.join(data.VARIANTS)}, got {variant!r}")
    if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not (math.isfinite(speed) and 0 < speed < 10):
        raise ValueError(f"{path}: field 'motion.speed': expected a speed in (0, 10) m/s, got {speed!r}")
    try:
        stored = data.load(variant, float(speed), mech)
    except ValueError as e:
        raise ValueError(f"{path}: field 'motion': {e}") from None
    return {"kind": "stride", "variant": variant, "speed": float(speed), "stored": stored}


def samples(motion: dict) -> int:
    return len(motion["stored"].t)


def label(motion: dict) -> str:
    st = motion["stored"]
    return (
        f"predicted stride (direct collocation, bench/studies/stride/data/{Path(st.path).name}): {st.variant} "
        f"variant at {st.speed:g} m/s, {st.period:.3f} s and {st.stride_length:.3f} m, {len(st.t)} nodes"
    )


def build(motion: dict, mech: Mechanism):
    from exo_bench.models.gait.motion import from_arrays

    st = motion["stored"]
    return from_arrays(mech, st.t, st.q, st.qd, st.qdd, source=f"stored stride {Path(st.path).name}")


def extra_files(scene) -> list[str]:
    """The files a stride scene writes beyond the outputs it declares (names by the file-name encoder)."""
    return [f"{file_stem(scene.name)}-{WINTER_FIGURE}.png"] if scene.wants("table") else []


def what(scene) -> str:
    st = scene.motion["stored"]
    return f"{scene.name}: {st.variant} variant at {st.speed:g} m/s ({scene.mechanism.name})"


def write_figures(scene, staging: Path) -> list[Path]:
    """Write :func:`extra_files` into ``staging``: our curves against Winter's."""
    from exo_bench.bench.output.provenance import save_figure
    from exo_bench.bench.studies.stride.comparison import compare

    c = compare(scene.mechanism, scene.motion["stored"])
    return [save_figure(winter_figure(c, what(scene)), staging / name) for name in extra_files(scene)]


def kinogram(scene):

    st = scene.motion["stored"]
    return stride_kinogram(scene.mechanism, st.t, st.q, what(scene))


def log_stride(scene):
    """A function ``(stream, times)`` that logs the stride's actuators and ground force to a rerun
    recording (``rr.send_columns``): joint moments (N·m) and telescopic rod forces (N) by actuator, and the
    ground force of each foot (N), under ``stride/``."""
    import rerun as rr

    from exo_bench.bench.studies.stride.actuators import actuators

    st = scene.motion["stored"]
    act = actuators(scene.mechanism, st.tau)
    # entity path parts through the file-name encoder: letters, digits, _ and - only
    series = {f"stride/joint_moments/{file_stem(n)}": act.moments[:, k] for k, n in enumerate(act.joint_names)}
    rods = [(k, n) for k, n in enumerate(act.rod_names) if n in st.telescopic]
    series |= {f"stride/rod_forces/{file_stem(n)}": act.forces[:, k] for k, n in rods}
    for f, foot in enumerate(data.FEET):
        for i, ax in enumerate(("fore-aft", "vertical")):
            series[f"stride/ground_force/{file_stem(foot)}_{ax}"] = st.grf[:, f, i]

    def log(stream, times) -> None:
        for entity, values in series.items():
            stream.send_columns(
                entity, indexes=[times], columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=float))
            )

    return log


# The stride's figures: its curves against Winter's over the cycle, and its kinogram.

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


__all__ = [
    "KINOGRAM_FRAMES",
    "PANELS",
    "WINTER_FIGURE",
    "build",
    "extra_files",
    "kinogram",
    "label",
    "load_motion",
    "log_stride",
    "samples",
    "stride_kinogram",
    "winter_figure",
]
