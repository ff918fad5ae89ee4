"""Figures of a :class:`exo_bench.bench.studies.study.Study`: the paper's Figs. 7-9 and the differences between methods.

* :func:`moments_figure` - the net joint moments (Fig. 7), the numbers of the scene report,
* :func:`forces_figure` - the longitudinal forces along the rods (Fig. 8),
* :func:`kinogram_figure` - stick-figure frames of the motion (Fig. 9),
* :func:`differences_figure` - every method minus the reference,
* :func:`overview_figure` - one picture of a scene (kinogram, moments, forces, differences).

**Which moments.** A study's ``tau`` are the generalised forces of the paper's *absolute*
angles (eq. 4 has ``M1 - M2`` on ``phi_1``). The moments figure shows the NET joint moments (the
moment the parent side exerts on everything beyond a joint, about it: :mod:`.net_moments`), the
numbers of the scene report's Plausibility table. The differences compare the methods in the joint
coordinates, ``tau_joint = G^-T tau`` with ``G`` the constant map ``q_joint = G q`` of
:func:`exo_bench.models.engines.pinocchio_backend.build_model`, whose elevation rows of a link with children
are its joint's moment minus its children's. The rod forces ``F_k`` are the same in both sets,
because the column of ``G`` of ``l_k`` is a unit vector, so ``F_k = tau_joint[len_k] = tau[l_k]``.
Every figure says in its title which it shows, with units and sign conventions.

Figures are built with matplotlib's object API (no pyplot, no global backend switch) and are
saved atomically by :func:`save_figure`.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from matplotlib.figure import Figure

# The figures' parts, one responsibility each, re-exported here as the scene figures' interface.
from exo_bench.bench.output.figures.curves import (  # noqa: F401
    SCALE_RATIO,
    ZERO_FRACTION,
    ScaleGroups,
    curve_colors,
    differences_figure,
    forces_figure,
    group_by_scale,
    nonfinite_notes,
    reference_method,
    scale_caption,
)
from exo_bench.bench.output.figures.kinogram import (  # noqa: F401
    KINOGRAM_FIRST_ALPHA,
    KINOGRAM_MAX_AREA,
    Projection,
    ground_label,
    kinogram_figure,
    kinogram_frames,
    overview_figure,
    projections,
    trail_points,
)
from exo_bench.bench.output.figures.net_moments import joint_labels, moments_figure, net_moment_curves  # noqa: F401
from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT, link_color, method_color  # noqa: F401
from exo_bench.bench.output.provenance import save_figure  # noqa: F401 (re-exported: the scene figures' writer)
from exo_bench.models.engines.joint_coordinates import (  # noqa: F401
    JointBasis,
    force_labels,
    generalised_moment_labels,
    generalised_moments,
    joint_basis,
    joint_quantities,
    moment_labels,
    moments_and_forces,
)

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


__all__ = [
    "FIGURES",
    "JointBasis",
    "Projection",
    "ScaleGroups",
    "TEXT_PT",
    "curve_colors",
    "differences_figure",
    "force_labels",
    "forces_figure",
    "generalised_moment_labels",
    "generalised_moments",
    "ground_label",
    "group_by_scale",
    "joint_basis",
    "joint_quantities",
    "kinogram_figure",
    "kinogram_frames",
    "link_color",
    "method_color",
    "moment_labels",
    "moments_and_forces",
    "moments_figure",
    "nonfinite_notes",
    "overview_figure",
    "projections",
    "reference_method",
    "save_figure",
    "scene_figure",
    "trail_points",
    "write_plots",
]
