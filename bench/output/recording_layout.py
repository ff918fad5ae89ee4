"""Where a scene's recording draws things (:mod:`exo_bench.bench.output.recording`): the point masses'
world positions, the trails, the masses' radii, and the viewer layout saved with the file (its
blueprint: the 3D view beside the joint moments, rod forces and differences, one plot per scale group).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import math
import re

import numpy as np
import rerun.blueprint as rrb

from exo_bench.bench.output.figures.curves import SCALE_RATIO, group_by_scale, reference_method, scale_caption

from exo_bench.models.engines.joint_coordinates import moments_and_forces
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.files.names import file_stem

if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study

#: Trails show where the trail points were over this many seconds.
TRAIL_SECONDS = 0.2
#: Points per trail (the trail is subsampled; the newest point is the current one).
TRAIL_POINTS = 11
#: Radius (m) of the heaviest point mass; the others scale with mass^(1/3) (sphere volume ∝ mass).
MAX_MASS_RADIUS = 0.05


# ----------------------------------------------------------------------------- geometry
def world_positions(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """Point-mass positions in the 3D viewer frame (z up), ``(S, n, 3, 3)``; planar models lie in x-z."""
    P = point_mass_positions(mech, q)
    if mech.dim == 3:
        return P
    return np.stack([P[..., 0], np.zeros_like(P[..., 0]), P[..., 1]], axis=-1)


def trail_indices(t: np.ndarray, seconds: float = TRAIL_SECONDS, points: int = TRAIL_POINTS) -> np.ndarray:
    """Sample indices of every frame's trail, oldest first, ``(S, points)``; the last column is the
    frame itself. Before ``seconds`` have passed the trail starts at the first sample."""
    S = t.shape[0]
    dt = float(np.median(np.diff(t))) if S > 1 else 1.0
    back = np.round(np.linspace(seconds / dt, 0.0, points)).astype(int)  # samples back, within dt/2 of exact
    return np.clip(np.arange(S)[:, None] - back[None, :], 0, S - 1)


def trail_entity(name: str) -> str:
    """The entity name of a trail point's name (``"stance_thigh end (hip)"`` -> ``stance_thigh_end_hip``):
    the file-name encoder's stem (:func:`exo_bench.models.files.names.file_stem`), its runs of ``_`` as one."""
    return re.sub(r"_+", "_", file_stem(name)).strip("_") or "unnamed"


def mass_radii(mech: Mechanism) -> np.ndarray:
    """Sphere radius of every point mass, ``(n*3,)``: proportional to mass^(1/3)."""
    m = mech.mass_array.reshape(-1)
    return MAX_MASS_RADIUS * np.cbrt(m / m.max())


# ----------------------------------------------------------------------------- layout
def _groups(study: Study, part: int) -> tuple:
    ok = study.ok_methods()
    if not ok:
        return None, {}
    taus = {m: study.results[m].tau for m in ok}  # ok methods: each produced tau
    data = {m: moments_and_forces(study.mechanism, tau)[part] for m, tau in taus.items() if tau is not None}
    # Groups follow the reference method's scales; the other methods' curves share its groups.
    ref_method = reference_method(study)
    assert ref_method is not None, "ok methods exist, so a reference method does"
    ref = data[ref_method]
    return group_by_scale(np.where(np.isfinite(ref), np.abs(ref), 0.0).max(axis=0), SCALE_RATIO), data


def _group_entity(groups, g: int) -> str:
    top = groups.maxima[groups.groups[g][0]]
    return f"group{g + 1}_max{math.ceil(top):d}"


def blueprint(study: Study) -> rrb.Blueprint:
    """The saved layout: the 3D view (and the recording's description) on the left; joint moments
    (a tab with the paper's generalised moments beside it), rod forces and the differences between
    methods on the right, one plot per scale group."""
    mech = study.mechanism
    ok = study.ok_methods()
    ref = reference_method(study)
    P = world_positions(mech, study.motion.q)
    lo, hi = P.reshape(-1, 3).min(axis=0), P.reshape(-1, 3).max(axis=0)
    centre = 0.5 * (lo + hi)
    size = float(max(hi - lo)) or 1.0
    eye = rrb.EyeControls3D(
        position=centre + np.array([0.62, -1.2, 0.2]) * size, look_target=centre, eye_up=[0.0, 0.0, 1.0]
    )
    left = rrb.Vertical(
        rrb.Spatial3DView(
            origin="world",
            name=f"{study.name}: rods, point masses (radius ∝ mass^⅓), trails",
            eye_controls=eye,
            line_grid=rrb.LineGrid3D(visible=True, spacing=0.1),
        ),
        rrb.TextDocumentView(origin="meta", name="About this recording"),
        row_shares=[3, 2],
    )
    right: list = []
    if ok:
        mg, _ = _groups(study, 0)
        fg, _ = _groups(study, 1)
        moment_views = [
            rrb.TimeSeriesView(
                origin=f"moments/{_group_entity(mg, g)}", name=f"Joint moments, {scale_caption(mg, g, 'N·m', 'M')}"
            )
            for g in range(len(mg.groups))
        ]
        if mg.zero:
            moment_views.append(
                rrb.TimeSeriesView(origin="moments/zero", name="Joint moments ≈ 0 (max below 1e-9 of the largest, N·m)")
            )
        force_views = [
            rrb.TimeSeriesView(
                origin=f"forces/{_group_entity(fg, g)}", name=f"Rod forces, {scale_caption(fg, g, 'N', 'F')}"
            )
            for g in range(len(fg.groups))
        ]
        if fg.zero:
            force_views.append(
                rrb.TimeSeriesView(origin="forces/zero", name="Rod forces ≈ 0 (max below 1e-9 of the largest, N)")
            )
        right.append(
            rrb.Tabs(
                rrb.Grid(
                    *moment_views,
                    grid_columns=2 if len(moment_views) > 2 else len(moment_views),
                    name="Joint moments τ_joint = G⁻ᵀτ (N·m), Fig. 7",
                ),
                rrb.TimeSeriesView(
                    origin="generalised", name="Generalised moments τ of the absolute angles (N·m), the paper's eq. 4"
                ),
                active_tab=0,
                name="moments",
            )
        )
        right.append(rrb.Horizontal(*force_views, name="Rod forces F (N), Fig. 8"))
        if len(ok) > 1:
            right.append(
                rrb.Horizontal(
                    rrb.TimeSeriesView(origin="differences/moments", name=f"Δ joint moments, method − {ref} (N·m)"),
                    rrb.TimeSeriesView(origin="differences/forces", name=f"Δ rod forces, method − {ref} (N)"),
                    name="differences",
                )
            )
    else:
        right.append(rrb.TextDocumentView(origin="meta", name="No method produced tau"))
    return rrb.Blueprint(
        rrb.Horizontal(left, rrb.Vertical(*right, row_shares=[5, 3, 3][: len(right)]), column_shares=[2, 3]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
    )
