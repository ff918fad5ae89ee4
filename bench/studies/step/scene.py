"""The scene motion ``kind = "step"``: the stored predicted step of the scene's mechanism, walked, and its
kinogram (:func:`walking_kinogram`: frames drawn as it walks).

In a scene file::

    mechanism = "exo5-3d"
    [motion]
    kind = "step"          # the stored step bench/studies/step/data/<file_stem(mechanism)>-step.npz
    steps = 2              # how many steps to walk (default 2): each one after the first mirrored

The stored step is looked up by the mechanism's name (through the file-name encoder, inside the data
folder) and walked only if it was solved for this very mechanism (equal dimension, g, tree, signs,
masses, fractions and link names: :mod:`exo_bench.bench.studies.step.identity`); any other mechanism,
whatever its name, is refused in one line saying how to solve a step for it.

The motion is :func:`exo_bench.bench.studies.step.data.walking_motion`: the collocation points of the stored step, and for
each further step the same points again (the leg swap relabels the links, so link 1 is always the stance
shin; in 3D the other leg is the mirror image) with the support point O moved to the new foot.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from exo_bench.bench.studies.step import data
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.bench.output.figures.curves import _header
from exo_bench.bench.output.figures.scene_figures import projections
from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT, link_color
from exo_bench.bench.studies.step.data import WalkingMotion
from exo_bench.bench.studies.study import Study
from exo_bench.models.mechanism.kinematics import point_mass_positions


def load_motion(path: Path, m: dict, mech: Mechanism) -> dict:
    """The ``[motion]`` table of a step scene, checked: ``{"kind", "steps", "stored"}``."""
    steps = m.get("steps", 2)
    if not isinstance(steps, int) or isinstance(steps, bool) or steps < 1:
        raise ValueError(f"{path}: field 'motion.steps': expected an integer >= 1, got {steps!r}")
    try:
        stored = data.load(mech)  # looked up by name in the data folder, reused only for an equal mechanism
    except ValueError as e:
        raise ValueError(f"{path}: field 'mechanism': {e}") from None
    return {"kind": "step", "steps": steps, "stored": stored}


def samples(motion: dict) -> int:
    K = len(motion["stored"].t)
    return K + (motion["steps"] - 1) * (K - 1)


def label(motion: dict) -> str:
    st = motion["stored"]
    return (
        f"predicted step (direct collocation, bench/studies/step/data/{st.file_name}): {motion['steps']} step(s) "
        f"of {st.duration:.3f} s and {st.step_length:.3f} m at {st.settings.speed:g} m/s, "
        f"{len(st.t)} collocation points each"
    )


def build(motion: dict, mech: Mechanism):
    return data.walking_motion(motion["stored"], mech, motion["steps"])


# The kinogram of a walking motion (:class:`exo_bench.bench.studies.step.data.WalkingMotion`): frames drawn as
# it walks.

#: Frames per step in the kinogram.
FRAMES_PER_STEP = 7
#: Link i of an odd step is the physical leg of link PHYSICAL[i] of the first step.
PHYSICAL = (3, 2, 1, 0, 4)


def origin(study: Study) -> np.ndarray:
    """Where O stands at each sample, ``(S, dim)``: the study's motion must be a :class:`WalkingMotion`."""
    if not isinstance(study.motion, WalkingMotion):
        raise TypeError(f"study {study.name!r}: expected a WalkingMotion, got {type(study.motion).__name__}")
    return study.motion.origin


def world_points(study: Study) -> np.ndarray:
    """Point-mass positions in the world, ``(S, n, 3, dim)``: relative to O plus where O stands."""
    P = point_mass_positions(study.mechanism, study.motion.q)
    return P + origin(study)[:, None, None, :]


def step_index(study: Study) -> np.ndarray:
    """Which step each sample belongs to (0, 1, ...), from the support point's moves."""
    o = origin(study)[:, 0]
    return np.concatenate([[0], np.cumsum(np.abs(np.diff(o)) > 0)])


def walking_kinogram(study: Study, frames_per_step: int = FRAMES_PER_STEP) -> Figure:
    mech = study.mechanism
    W = world_points(study)
    k_of = step_index(study)
    steps = int(k_of.max()) + 1
    idx = np.unique(
        np.concatenate(
            [
                np.flatnonzero(k_of == k)[
                    np.linspace(0, np.count_nonzero(k_of == k) - 1, frames_per_step).round().astype(int)
                ]
                for k in range(steps)
            ]
        )
    )
    proj = projections(mech)[0]
    hx, vx = proj.axes
    masses = mech.mass_array
    area = masses / masses.max() * 120.0
    lo, hi = float(W[..., hx].min()) - 0.1, float(W[..., hx].max()) + 0.1
    top = float(W[..., vx].max()) + 0.1
    width = min(22.0, max(11.0, 7.0 * (hi - lo)))
    fig = Figure(figsize=(width, width * (top + 0.25) / (hi - lo) + 2.2), layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    ax.plot([lo, hi], [0, 0], color="0.45", lw=1.0, ls="--", zorder=1, gid="floor")
    feet = np.unique(origin(study)[:, hx])
    ax.plot(feet, np.zeros_like(feet), "k^", ms=8, ls="none", zorder=4, gid="support")
    hip = W[:, 1, 2]
    ax.plot(hip[:, hx], hip[:, vx], color="k", lw=1.0, ls=":", zorder=1, gid="hip-path")
    for k in range(steps):
        sel = k_of == k
        ax.plot(W[sel, 3, 2, hx], W[sel, 3, 2, vx], color="0.3", lw=0.9, ls="-.", zorder=1, gid=f"swing-foot-path:{k}")
    for s_ in idx:
        k = k_of[s_]
        for i in range(mech.nlinks):
            c = link_color(PHYSICAL[i] if k % 2 else i)
            P = W[s_, i]
            ax.plot(
                [P[0, hx], P[2, hx]],
                [P[0, vx], P[2, vx]],
                color=c,
                lw=2.0,
                solid_capstyle="round",
                zorder=2,
                gid=f"rod:{s_}:{i}",
            )
            ax.scatter(P[:, hx], P[:, vx], s=area[i], c=[c] * 3, edgecolors="k", linewidths=0.4, zorder=3)
    ax.set_xlim(lo, hi)
    ax.set_ylim(-0.05, top)
    ax.set_aspect("equal")
    ax.set_xlabel(proj.labels[0] + ", walking direction", fontsize=TEXT_PT)
    ax.set_ylabel(proj.labels[1], fontsize=TEXT_PT)
    ax.tick_params(labelsize=TEXT_PT)
    handles = [
        Line2D([], [], color=link_color(0), lw=2, label="leg A shin (stance in step 1, swing in step 2)"),
        Line2D([], [], color=link_color(1), lw=2, label="leg A thigh"),
        Line2D([], [], color=link_color(2), lw=2, label="leg B thigh (swing in step 1, stance in step 2)"),
        Line2D([], [], color=link_color(3), lw=2, label="leg B shin"),
        Line2D([], [], color=link_color(4), lw=2, label="trunk"),
        Line2D([], [], color="k", ls=":", label="hip path"),
        Line2D([], [], color="0.3", ls="-.", label="swing foot path"),
        Line2D([], [], color="k", marker="^", ls="none", label="stance feet (support point O of each step)"),
        Line2D([], [], color="0.45", ls="--", label="floor"),
    ]
    fig.legend(handles=handles, fontsize=TEXT_PT, loc="outside lower center", ncols=3, frameon=False)
    t = study.motion.t
    fig.suptitle(
        _header(
            study,
            f"Kinogram drawn as it walks: {steps} step(s) over {t[-1] - t[0]:.2f} s, "
            f"{frames_per_step} frames per step at their place in the world ({proj.name}); each "
            "step after the first is the stored one mirrored (legs exchanged); dot area ∝ point mass",
        ),
        fontsize=TITLE_PT,
    )
    return fig


__all__ = [
    "FRAMES_PER_STEP",
    "PHYSICAL",
    "build",
    "label",
    "load_motion",
    "origin",
    "samples",
    "step_index",
    "walking_kinogram",
    "world_points",
]
