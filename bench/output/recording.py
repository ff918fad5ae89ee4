"""A rerun recording (``.rrd``) of a :class:`exo_bench.bench.studies.study.Study`: where it draws things, its
viewer layout, writing it, and checking and picturing it with the rerun executable.

One recording per scene holds, on the timeline ``time`` (seconds since the start of the motion):

* ``world/...`` - the model in 3D: ``world/rods`` (one line strip per rod), ``world/masses``
  (point masses as spheres of radius proportional to mass^(1/3)), ``world/support`` (the support
  point O, static) and ``world/trails/<point>`` (the last 0.2 s of the points
  :func:`exo_bench.bench.output.figures.scene_figures.trail_points` names after the mechanism's links, e.g. the hip and the swing ankle).
  Planar models are drawn in the x-z plane with z up, so one viewer layout serves both.
* ``moments/<scale group>/<method>`` - the joint moments ``tau_joint = G^-T tau`` (N·m), grouped
  by the scale of their maxima like the paper's Fig. 7;
  ``forces/<scale group>/<method>`` - the rod forces ``F_k`` (N), Fig. 8;
  ``generalised/<reference method>`` - the paper's generalised moments of the absolute angles (N·m);
  ``differences/moments/<method>``, ``differences/forces/<method>`` - method minus reference.
* ``meta`` - what the recording holds and how it was made (rerun-sdk version, exo-bench commit,
  methods, quantity conventions) and the loads beside level walking (:mod:`exo_bench.bench.studies.plausibility`),
  as a Markdown document and as plain values.

Every time series is sent with ``send_columns`` (one call per entity, all samples at once); the
layout is a saved blueprint (the file opens with it). The file is written to a temporary name
beside the target and renamed into place when complete.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from matplotlib.colors import to_rgb

from exo_bench.bench.output.figures.curves import (
    SCALE_RATIO,
    curve_colors,
    group_by_scale,
    nonfinite_notes,
    reference_method,
    scale_caption,
)
from exo_bench.bench.output.figures.palette import link_color
from exo_bench.bench.output.figures.scene_figures import trail_points
from exo_bench.models.engines.joint_coordinates import (
    force_labels,
    generalised_moment_labels,
    generalised_moments,
    moment_labels,
    moments_and_forces,
)
from exo_bench.bench.output.provenance import machine_info
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.files import file_stem


# Where a scene's recording draws things: the point masses' world
# positions, the trails, the masses' radii, and the viewer layout saved with the file (its blueprint: the 3D
# view beside the joint moments, rod forces and differences, one plot per scale group).

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
    the file-name encoder's stem (:func:`exo_bench.models.files.file_stem`), its runs of ``_`` as one."""
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


# The rerun executable beside this Python's rerun-sdk: checking a recording (``rerun rrd verify``) and taking a
# picture of it in the viewer (for the README and the scene reports).


def rerun_executable() -> Path | None:
    """The ``rerun`` command installed with this Python's rerun-sdk, if any."""
    exe = Path(sys.executable).with_name("rerun")
    return exe if exe.exists() else None


def verify_recording(path: str | Path) -> str:
    """Run ``rerun rrd verify`` on a recording; return its report, raise ValueError if it fails.

    (``rerun rrd verify`` exits 0 on a file that is not a recording at all and only says
    "0 files verified", so the report is checked too.)"""
    exe = rerun_executable()
    if exe is None:
        raise OSError(f"rerun executable not found next to {sys.executable}")
    res = subprocess.run([str(exe), "rrd", "verify", str(path)], capture_output=True, text=True, timeout=120)
    report = (res.stdout + res.stderr).strip()
    if res.returncode != 0 or "1 file verified without error" not in report:
        raise ValueError(
            f"{path}: rerun rrd verify failed (exit {res.returncode}): {report.splitlines()[-1:] or report}"
        )
    return report


def screenshot(path: str | Path, png: str | Path, size: str = "1600x900", timeout: float = 300.0) -> Path:
    """A picture of the recording in the rerun viewer with its saved layout, written atomically.

    Runs ``rerun --window-size SIZE --screenshot-to PNG FILE``, which needs a display (an X server;
    ``Xvfb`` with Mesa's software Vulkan works: ``--renderer vulkan``) and is slow on a CPU renderer.
    The viewer renders at twice the window size on a high-DPI setup; the picture is scaled back to
    ``size``."""
    from PIL import Image

    from exo_bench.models.files import atomic_write

    exe = rerun_executable()
    if exe is None:
        raise OSError(f"rerun executable not found next to {sys.executable}")
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        raise OSError("screenshot: no display (set DISPLAY, e.g. run under Xvfb)")
    png = Path(png)
    with tempfile.TemporaryDirectory() as tmp:
        shot = Path(tmp) / "shot.png"
        res = subprocess.run(
            [str(exe), "--renderer", "vulkan", "--window-size", size, "--screenshot-to", str(shot), str(path)],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
        if res.returncode != 0 or not shot.exists():
            last = (res.stderr or res.stdout).strip().splitlines()[-1:] or ["no output"]
            raise OSError(f"screenshot of {path}: rerun exited {res.returncode}: {last[0]}")
        w, h = (int(x) for x in size.split("x"))
        img = Image.open(shot).convert("RGB")
        if img.size != (w, h):
            img = img.resize((w, h), Image.Resampling.LANCZOS)
        import io

        buf = io.BytesIO()
        img.save(buf, format="PNG", optimize=True)
    return atomic_write(png, buf.getvalue())


if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study

APPLICATION_ID = "exo-bench"
TIMELINE = "time"

CONVENTIONS = (
    "moments/: joint moments tau_joint = G^-T tau (N·m) about the joints of Pinocchio's model "
    "(L<k>_phi: relative azimuth phi_k - phi_parent; L<k>_psi: elevation psi_k), the paper's Fig. 7; "
    "forces/: rod forces F_k (N), the same in joint and absolute coordinates, Fig. 8; "
    "generalised/: the paper's generalised moments of the absolute angles (eq. 4 has M1 - M2 on phi_1); "
    "differences/: method minus reference, in joint moments and rod forces."
)


def _rgb(color: str) -> tuple[int, int, int]:
    r, g, b = (int(round(255 * c)) for c in to_rgb(color))
    return r, g, b


_COLOUR_NAMES = {
    "#1f77b4": "blue",
    "#d62728": "red",
    "#2ca02c": "green",
    "#ff7f0e": "orange",
    "#9467bd": "purple",
    "#8c564b": "brown",
    "#e377c2": "pink",
    "#17becf": "cyan",
    "#bcbd22": "olive",
    "#7f7f7f": "grey",
}


def _colour_name(color: str) -> str:
    return _COLOUR_NAMES.get(color, color)


def _lighter(color: str, k: int) -> tuple[int, int, int]:
    """The colour of a curve for the k-th method: the reference keeps it, others are paler."""
    r = np.array(_rgb(color), dtype=float)
    f = 0.0 if k == 0 else min(0.25 + 0.12 * (k - 1), 0.6)
    red, green, blue = (int(round(x)) for x in r + (255 - r) * f)
    return red, green, blue


# ----------------------------------------------------------------------------- description
def _describe(study: Study, loads: str | None = None) -> tuple[str, dict]:
    from exo_bench.models.files import markdown_code, markdown_text

    mech = study.mechanism
    ok = study.ok_methods()
    ref = reference_method(study)
    commit = machine_info()["commit"]
    agreement = study.agreement() if ref == study.reference else {}
    lines = [
        f"# {study.name}: {study.motion_label}",
        "",
        f"Model {markdown_code(mech.name)}: {mech.dim}D, {mech.nlinks} links "
        f"({', '.join(markdown_text(n) for n in mech.names)}), "
        f"total mass {mech.total_mass:.4g} kg. {study.motion.t.shape[0]} samples over "
        f"{study.motion.t[-1] - study.motion.t[0]:.4g} s on the timeline `{TIMELINE}`.",
    ]
    if loads:
        lines += ["", "## Loads", "", loads]
    lines += ["", "## Methods", "", f"Methods: {', '.join(ok) if ok else 'none succeeded'}; reference: {ref}."]
    for m, r in study.results.items():
        if r.skipped:
            lines.append(f"- {m}: skipped ({r.skipped})")
        elif r.error:
            lines.append(f"- {m}: failed ({r.error})")
        elif m in agreement and m != ref:
            lines.append(f"- {m}: max |τ − τ_{ref}| / max |τ_{ref}| = {agreement[m]:.2e}")
    lines += [f"- **{w}**" for w in nonfinite_notes(study)]
    lines += [
        "",
        "## Quantities",
        "",
        "- `moments/`: the **joint moments** τ_joint = G⁻ᵀ τ (N·m) about the joints of Pinocchio's model "
        "(`L<k>_phi`: relative azimuth φ_k − φ_parent; `L<k>_psi`: elevation ψ_k) — the paper's Fig. 7, "
        "grouped by the scale of their maxima. Only the reference method's curves are shown at first; the "
        "other methods' curves (paler) are hidden, click their legend entries to show them.",
        "- `forces/`: the **rod forces** F_k (N) along each rod — the paper's Fig. 8; the same in joint and "
        "absolute coordinates (l_k maps to itself).",
        "- `generalised/`: the paper's **generalised moments** of the absolute angles (eq. 4 has M1 − M2 on φ1), "
        "reference method only.",
        "- `differences/`: method − reference, in joint moments and rod forces.",
        "- `world/`: rods, point masses (radius ∝ mass^⅓), the support point O, trails of the last "
        f"{TRAIL_SECONDS:g} s of {', '.join(markdown_text(p) for p in trail_points(mech))}"
        + ("; the planar model is drawn in the x–z plane, z up." if mech.dim == 2 else "; z up.")
        + " Link colours: "
        + ", ".join(f"{i + 1} {markdown_text(mech.names[i])} {_colour_name(link_color(i))}" for i in range(mech.nlinks))
        + ".",
        "",
        f"Written by exo-bench at commit {commit} with rerun-sdk {rr.__version__}.",
    ]
    values = {
        "scene": study.name,
        "model": mech.name,
        "motion": study.motion_label,
        "rerun_sdk_version": rr.__version__,
        "exo_bench_commit": commit,
        "methods": list(study.results),
        "methods_ok": ok,
        "reference": ref or "",
        "samples": int(study.motion.t.shape[0]),
        "conventions": CONVENTIONS,
    }
    return "\n".join(lines) + "\n", values


# ----------------------------------------------------------------------------- writing
def _send_series(
    stream: rr.RecordingStream,
    entity: str,
    times: rr.TimeColumn,
    values: np.ndarray,
    names: list[str],
    colors: list,
    width: float,
    visible: bool = True,
) -> None:
    """All samples of one entity's curves in one call, and their static styling."""
    stream.send_columns(entity, indexes=[times], columns=rr.Scalars.columns(scalars=values))
    stream.log(
        entity,
        rr.SeriesLines(names=names, colors=colors, widths=[width] * len(names), visible_series=[visible] * len(names)),
        static=True,
    )


def _log_world(stream: rr.RecordingStream, study: Study, times: rr.TimeColumn) -> None:
    mech = study.mechanism
    S, n = study.motion.t.shape[0], mech.nlinks
    P = world_positions(mech, study.motion.q)  # (S, n, 3, 3)
    origin = getattr(study.motion, "origin", None)  # a walking motion: where O stands
    if origin is not None:
        P = (
            P
            + (origin if mech.dim == 3 else np.stack([origin[:, 0], 0 * origin[:, 0], origin[:, 1]], -1))[:, None, None]
        )
    P = P.astype(np.float32)
    link_rgb = [_rgb(link_color(i)) for i in range(n)]
    stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    stream.log(
        "world/support",
        rr.Points3D([[0.0, 0.0, 0.0]], radii=0.03, colors=[(0, 0, 0)], labels=["O (support point)"]),
        static=True,
    )
    # Rods: one strip from the start to the end of every link, per sample.
    strips = np.stack([P[:, :, 0], P[:, :, 2]], axis=2).reshape(S * n, 2, 3)
    stream.send_columns(
        "world/rods", indexes=[times], columns=rr.LineStrips3D.columns(strips=strips).partition([n] * S)
    )
    stream.log(
        "world/rods",
        rr.LineStrips3D.from_fields(
            colors=link_rgb, radii=[0.012] * n, labels=[f"{i + 1} {mech.names[i]}" for i in range(n)], show_labels=False
        ),
        static=True,
    )
    # Point masses: three per link, sized by mass.
    stream.send_columns(
        "world/masses",
        indexes=[times],
        columns=rr.Points3D.columns(positions=P.reshape(S * n * 3, 3)).partition([3 * n] * S),
    )
    labels = [f"m{i + 1},{b} = {mech.masses[i][b]:.4g} kg ({mech.names[i]})" for i in range(n) for b in range(3)]
    stream.log(
        "world/masses",
        rr.Points3D.from_fields(
            radii=mass_radii(mech), colors=[c for c in link_rgb for _ in range(3)], labels=labels, show_labels=False
        ),
        static=True,
    )
    # Trails: the recent path of the trail points.
    idx = trail_indices(study.motion.t)
    for name, (i, b) in trail_points(mech).items():
        path = P[idx, i, b]  # (S, points, 3)
        entity = f"world/trails/{trail_entity(name)}"
        stream.send_columns(entity, indexes=[times], columns=rr.LineStrips3D.columns(strips=path).partition([1] * S))
        stream.log(
            entity,
            rr.LineStrips3D.from_fields(
                colors=[(200, 200, 200)], radii=[0.004], labels=[f"{name}, last {TRAIL_SECONDS:g} s"], show_labels=False
            ),
            static=True,
        )


def _log_series(stream: rr.RecordingStream, study: Study, times: rr.TimeColumn) -> None:
    mech = study.mechanism
    ok = study.ok_methods()
    ref = reference_method(study)
    if ref is None:  # no method produced tau: no series to record
        return
    order = [ref] + [m for m in ok if m != ref]
    for part, root, labels, kind in (
        (0, "moments", moment_labels(mech), "moments"),
        (1, "forces", force_labels(mech), "forces"),
    ):
        groups, data = _groups(study, part)
        colors = curve_colors(mech, kind)
        entities = [(_group_entity(groups, g), list(groups.groups[g])) for g in range(len(groups.groups))]
        if groups.zero:
            entities.append(("zero", list(groups.zero)))
        for k, m in enumerate(order):
            for entity, cols in entities:
                _send_series(
                    stream,
                    f"{root}/{entity}/{m}",
                    times,
                    data[m][:, cols],
                    [f"{labels[j]} ({m})" for j in cols],
                    [_lighter(colors[j], k) for j in cols],
                    2.0 if k == 0 else 1.2,
                    visible=k == 0,
                )
            if m != ref:
                diff = moments_and_forces(mech, study.tau(m) - study.tau(ref))[part]
                _send_series(
                    stream,
                    f"differences/{root}/{m}",
                    times,
                    diff,
                    [f"Δ{labels[j]} ({m} − {ref})" for j in range(len(labels))],
                    [_rgb(c) for c in colors],
                    1.2,
                )
    # The paper's generalised moments, for the reference method only (the others differ from it by
    # G^T times their joint differences, which are recorded above).
    gl = generalised_moment_labels(mech)
    gcol = [_rgb(link_color(j % mech.nlinks + (5 if j >= mech.nlinks else 0))) for j in range(len(gl))]
    _send_series(
        stream,
        f"generalised/{ref}",
        times,
        generalised_moments(mech, study.tau(ref)),
        [f"{x} ({ref})" for x in gl],
        gcol,
        2.0,
    )


def write_recording(study: Study, path: str | Path, loads: str | None = None, extra=None) -> Path:
    """Write the scene's recording with its default blueprint to ``path`` (atomically); ``loads``
    is the Markdown of the loads beside level walking (:func:`exo_bench.bench.studies.plausibility.text`),
    its section of the description (none when None); ``extra(stream, times)``, when given, logs a
    scene's own series (the stride's actuators: :func:`exo_bench.bench.studies.stride.scene.log_stride`)."""
    from exo_bench.models.files import atomic_path

    with atomic_path(path) as tmp:
        stream = rr.RecordingStream(APPLICATION_ID, send_properties=True)
        stream.save(str(tmp), default_blueprint=blueprint(study))
        stream.send_recording_name(study.name)
        times = rr.TimeColumn(TIMELINE, duration=np.asarray(study.motion.t, dtype=float))
        text, values = _describe(study, loads)
        stream.log("meta", rr.TextDocument(text, media_type=rr.MediaType.MARKDOWN), static=True)
        stream.log("meta", rr.AnyValues(**values), static=True)
        _log_world(stream, study, times)
        if study.ok_methods():
            _log_series(stream, study, times)
        if extra is not None:
            extra(stream, times)
        stream.flush()
        stream.disconnect()  # closes the file sink and writes the footer
    return Path(path)


__all__ = [
    "APPLICATION_ID",
    "CONVENTIONS",
    "TIMELINE",
    "blueprint",
    "mass_radii",
    "reference_method",
    "rerun_executable",
    "screenshot",
    "trail_entity",
    "trail_indices",
    "trail_points",
    "verify_recording",
    "world_positions",
    "write_recording",
]
