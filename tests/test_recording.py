"""The rerun recordings, read back with ``rerun.chunk.RrdReader`` and checked against the physics.

Expected values come from independent computations: Pinocchio's RNEA in its own joint coordinates
(``joint_torques``) for the joint moments, the paper's length rows of tau for the rod forces, the
kinematics module for the 3D geometry, and a synthetic second method with known noise for the
differences.
"""

from __future__ import annotations

import os
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from exo_bench.bench.output import recording
from exo_bench.bench.output.figures.curves import SCALE_RATIO
from exo_bench.models.engines.joint_coordinates import force_labels, moment_labels
from exo_bench.bench.output.recording import (
    TRAIL_SECONDS,
    rerun_executable,
    trail_entity,
    trail_indices,
    verify_recording,
    write_recording,
)
from exo_bench.bench.output.figures.scene_figures import trail_points
from exo_bench.bench.studies.study import MethodResult, Study, run_methods
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.gait.motion import GaitParams, gait, planar_gait
from exo_bench.models.engines.pinocchio_backend import build_model, joint_torques
from exo_bench.models.mechanism.presets import exo5, fig2a, fig2b, fig5

NOISE = 1e-6


def _study(mech, motion_fn, samples: int, noisy: bool) -> Study:
    t = np.linspace(0.0, GaitParams().T, samples, endpoint=False)
    study = run_methods(mech.name, mech, motion_fn(mech, t), "test gait", ["pinocchio"])
    if noisy:
        ref = study.results["pinocchio"].tau
        noise = NOISE * np.random.default_rng(7).standard_normal(ref.shape)
        study.results["noisy"] = MethodResult("noisy", ref + noise, 1e-6)
        study.results["slow"] = MethodResult("slow", skipped="over the time budget of 1 s")
        study.results["broken"] = MethodResult("broken", error="RuntimeError: singular matrix")
        study._noise = noise
    return study


def _loads(study):
    """The loads section as the main job passes it (exo_bench.bench.studies.scene_run.run_scene)."""
    from exo_bench.bench.studies.plausibility import plausibility, text

    p = plausibility(study)
    return None if p is None else text(p)


@pytest.fixture(scope="module")
def exo(tmp_path_factory):
    study = _study(exo5(3), gait, 150, noisy=True)
    path = write_recording(study, tmp_path_factory.mktemp("rrd") / "exo5-3d.rrd", loads=_loads(study))
    return study, path, _read(path)


@pytest.fixture(scope="module")
def planar(tmp_path_factory):
    study = _study(fig5(2), planar_gait, 90, noisy=False)
    path = write_recording(study, tmp_path_factory.mktemp("rrd") / "fig5-2d.rrd", loads=_loads(study))
    return study, path, _read(path)


class Recording:
    """Every component column of a recording, by entity: temporal rows sorted by time."""

    def __init__(self, path: Path):
        self.reader = RrdReader(path)
        self.temporal: dict[str, dict[str, object]] = defaultdict(dict)
        self.static: dict[str, dict[str, object]] = defaultdict(dict)
        self.times: dict[str, np.ndarray] = {}
        for chunk in self.reader.stream().to_chunks():
            rb = chunk.to_record_batch()
            entity = chunk.entity_path.lstrip("/")
            target = self.static if chunk.is_static else self.temporal
            order = None
            if not chunk.is_static:
                ns = rb.column("time").cast("int64").to_numpy()
                order = np.argsort(ns, kind="stable")
                self.times[entity] = ns[order]
            for name in rb.schema.names:
                if name in ("rerun.controls.RowId", "time"):
                    continue
                values = rb.column(name).to_pylist()
                if order is not None:
                    values = [values[i] for i in order]
                else:  # static: the last non-null row is what a viewer shows
                    values = [v for v in values if v is not None]
                    if not values:
                        continue
                    values = values[-1]
                target[entity][name] = values

    def scalars(self, entity: str) -> np.ndarray:
        return np.array(self.temporal[entity]["Scalars:scalars"], dtype=float)

    def names(self, entity: str) -> list[str]:
        return self.static[entity]["SeriesLines:names"]


def _read(path: Path) -> Recording:
    return Recording(path)


def _curves(rec: Recording, root: str, method: str) -> dict[str, np.ndarray]:
    """``name -> values`` of every curve recorded under ``root/<group>/<method>``."""
    out = {}
    for entity in rec.temporal:
        parts = entity.split("/")
        if len(parts) == 3 and parts[0] == root and parts[2] == method:
            vals = rec.scalars(entity)
            for k, name in enumerate(rec.names(entity)):
                assert name.endswith(f" ({method})")
                label = name[: -len(f" ({method})")]
                assert label not in out, f"{label} recorded twice for {method}"
                out[label] = vals[:, k]
    return out


def _expected_joint(study: Study, tau_joint: np.ndarray) -> tuple[dict, dict]:
    """Joint moments and rod forces by label, from arrays in Pinocchio's joint rows."""
    mech = study.mechanism
    names = build_model(mech).joint_names
    moments, forces = {}, {}
    for r, name in enumerate(names):
        k, kind = name.split("_")
        link = int(k[1:])
        if kind == "len":
            forces[f"F{link} {mech.names[link - 1]}"] = tau_joint[:, r]
        else:
            moments[f"M{'φ' if kind == 'phi' else 'ψ'}{link} {mech.names[link - 1]}"] = tau_joint[:, r]
    return moments, forces


# ----------------------------------------------------------------------------- time series
@pytest.mark.parametrize("which", ["exo", "planar"])
def test_joint_moments_in_the_recording_equal_pinocchio_rnea_in_joint_coordinates(which, request):
    study, _, rec = request.getfixturevalue(which)
    m = study.motion
    moments, _ = _expected_joint(study, joint_torques(study.mechanism, m.q, m.qd, m.qdd))
    got = _curves(rec, "moments", "pinocchio")
    assert set(got) == set(moments) == set(moment_labels(study.mechanism))
    scale = max(np.abs(v).max() for v in moments.values())
    for label, values in moments.items():
        assert np.abs(got[label] - values).max() <= 1e-10 * scale, label


def test_every_method_is_recorded_and_the_synthetic_one_carries_its_known_noise(exo):
    study, _, rec = exo
    G_inv = np.linalg.inv(build_model(study.mechanism).G)
    m = study.motion
    exact = joint_torques(study.mechanism, m.q, m.qd, m.qdd)
    moments, forces = _expected_joint(study, exact + study._noise @ G_inv)
    got_m, got_f = _curves(rec, "moments", "noisy"), _curves(rec, "forces", "noisy")
    assert set(got_m) == set(moments) and set(got_f) == set(forces)
    for label in moments:
        np.testing.assert_allclose(got_m[label], moments[label], rtol=0, atol=1e-9)
    for label in forces:
        np.testing.assert_allclose(got_f[label], forces[label], rtol=0, atol=1e-9)
    # Methods that produced nothing have no curves.
    assert not _curves(rec, "moments", "slow") and not _curves(rec, "moments", "broken")


@pytest.mark.parametrize("which", ["exo", "planar"])
def test_recorded_rod_forces_are_the_length_rows_of_the_paper_tau(which, request):
    """F_k is the same in joint and in absolute coordinates: the recorded force of rod k equals
    the paper's generalised force of l_k, and Pinocchio's prismatic joint force."""
    study, _, rec = request.getfixturevalue(which)
    mech, m = study.mechanism, study.motion
    tau = study.results["pinocchio"].tau
    got = _curves(rec, "forces", "pinocchio")
    _, rnea = _expected_joint(study, joint_torques(mech, m.q, m.qd, m.qdd))
    assert list(got) != [] and set(got) == set(force_labels(mech))
    for k in range(mech.nlinks):
        label = f"F{k + 1} {mech.names[k]}"
        np.testing.assert_allclose(got[label], tau[:, (mech.dim - 1) * mech.nlinks + k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(got[label], rnea[label], rtol=0, atol=1e-9)


def test_differences_are_method_minus_reference_in_joint_coordinates(exo):
    study, _, rec = exo
    G_inv = np.linalg.inv(build_model(study.mechanism).G)
    moments, forces = _expected_joint(study, study._noise @ G_inv)
    # (ref + noise) - ref loses the last bits of |tau|: a few ulps of the largest generalised force
    atol = 16 * np.finfo(float).eps * np.abs(study.results["pinocchio"].tau).max()
    dm, df = rec.scalars("differences/moments/noisy"), rec.scalars("differences/forces/noisy")
    for vals, expected, entity in (
        (dm, moments, "differences/moments/noisy"),
        (df, forces, "differences/forces/noisy"),
    ):
        names = [n.split(" (")[0].removeprefix("Δ") for n in rec.names(entity)]
        assert set(names) == set(expected)
        for k, label in enumerate(names):
            np.testing.assert_allclose(vals[:, k], expected[label], rtol=0, atol=atol)
    assert not any(e.startswith("differences/") and e.endswith("/pinocchio") for e in rec.temporal)


def test_generalised_moments_are_the_paper_angle_rows_of_tau(exo):
    study, _, rec = exo
    mech = study.mechanism
    vals = rec.scalars("generalised/pinocchio")
    tau = study.results["pinocchio"].tau
    np.testing.assert_array_equal(vals, tau[:, : 2 * mech.nlinks])
    assert rec.names("generalised/pinocchio")[0].startswith("Mφ1 (abs.)")


@pytest.mark.parametrize("which", ["exo", "planar"])
def test_every_time_series_has_one_row_per_sample_on_the_time_axis(which, request):
    study, _, rec = request.getfixturevalue(which)
    t_ns = np.round(study.motion.t * 1e9).astype(np.int64)
    assert rec.times, "no temporal data"
    for entity, ns in rec.times.items():
        assert ns.shape == t_ns.shape, entity
        assert np.abs(ns - t_ns).max() <= 1, entity


def test_time_series_grouped_by_scale_keep_each_curve_within_its_group_span(exo):
    study, _, rec = exo
    for root in ("moments", "forces"):
        for entity in [e for e in rec.temporal if e.startswith(root + "/group") and e.endswith("/pinocchio")]:
            maxima = np.abs(rec.scalars(entity)).max(axis=0)
            cap = int(entity.split("_max")[1].split("/")[0])  # group<k>_max<ceil of its largest>
            assert maxima.max() <= cap and maxima.max() > cap - 1, entity
            assert maxima.max() <= SCALE_RATIO * maxima.min(), entity


# ----------------------------------------------------------------------------- 3D scene
@pytest.mark.parametrize("which", ["exo", "planar"])
def test_rods_and_point_masses_sit_where_the_kinematics_puts_them(which, request):
    study, _, rec = request.getfixturevalue(which)
    mech = study.mechanism
    P = point_mass_positions(mech, study.motion.q)  # (S, n, 3, dim)
    if mech.dim == 2:  # the plane drawn as x-z, z up
        P = np.stack([P[..., 0], np.zeros_like(P[..., 0]), P[..., 1]], axis=-1)
    strips = np.array(rec.temporal["world/rods"]["LineStrips3D:strips"], dtype=float)  # (S, n, 2, 3)
    assert strips.shape == (P.shape[0], mech.nlinks, 2, 3)
    np.testing.assert_allclose(strips[:, :, 0], P[:, :, 0], atol=1e-6)
    np.testing.assert_allclose(strips[:, :, 1], P[:, :, 2], atol=1e-6)
    points = np.array(rec.temporal["world/masses"]["Points3D:positions"], dtype=float)  # (S, 3n, 3)
    np.testing.assert_allclose(points, P.reshape(P.shape[0], -1, 3), atol=1e-6)
    assert rec.static["world"]  # view coordinates: z up
    np.testing.assert_array_equal(np.array(rec.static["world/support"]["Points3D:positions"]), [[0, 0, 0]])


def test_point_mass_spheres_have_volume_proportional_to_mass(exo):
    study, _, rec = exo
    r = np.array(rec.static["world/masses"]["Points3D:radii"], dtype=float)
    m = study.mechanism.mass_array.reshape(-1)
    np.testing.assert_allclose(r**3 / m, (r**3 / m)[0], rtol=1e-5)


def test_trails_follow_the_hip_and_the_swing_ankle_over_the_last_fifth_of_a_second(exo):
    study, _, rec = exo
    mech = study.mechanism
    assert trail_points(mech) == {"stance_thigh end (hip)": (1, 2), "swing_shin end (swing ankle)": (3, 2)}
    P = point_mass_positions(mech, study.motion.q)
    t = study.motion.t
    for name, link in (("stance_thigh_end_hip", 1), ("swing_shin_end_swing_ankle", 3)):
        strips = np.array(rec.temporal[f"world/trails/{name}"]["LineStrips3D:strips"], dtype=float)  # (S, 1, k, 3)
        assert strips.shape[:2] == (len(t), 1)
        path = strips[:, 0]
        np.testing.assert_allclose(path[:, -1], P[:, link, 2], atol=1e-6)  # ends at the current point
        late = t >= TRAIL_SECONDS + 0.02
        i0 = np.flatnonzero(late)[0]
        # the oldest point lies about 0.2 s back along the same point's path
        j = np.argmin(np.linalg.norm(P[: i0 + 1, link, 2] - path[i0, 0], axis=1))
        assert abs((t[i0] - t[j]) - TRAIL_SECONDS) <= 0.5 * (t[1] - t[0]) + 1e-12


def test_trail_points_of_the_planar_scenes_are_named_after_their_links():
    """fig2b's branch point is the end of its shin (a knee, not a hip): names come from the links."""
    assert trail_points(fig2a(2)) == {"tip (thigh end)": (1, 2)}  # a chain: the free end of its last link
    assert trail_points(fig2b(2)) == {"shin end": (0, 2), "thigh end": (1, 2)}
    assert trail_points(fig5(2)) == {"stance_thigh end (hip)": (1, 2), "swing_shin end (swing ankle)": (3, 2)}
    assert trail_entity("stance_thigh end (hip)") == "stance_thigh_end_hip"


def test_trail_indices_look_back_a_fixed_time_and_never_before_the_start():
    t = np.linspace(0, 1, 101)
    idx = trail_indices(t, seconds=0.2, points=11)
    assert idx.shape == (101, 11)
    np.testing.assert_array_equal(idx[:, -1], np.arange(101))
    np.testing.assert_allclose(t[idx[60, -1]] - t[idx[60, 0]], 0.2)
    assert idx.min() == 0 and np.all(np.diff(idx, axis=1) >= 0)


# ----------------------------------------------------------------------------- meta and layout
def test_meta_records_the_sdk_version_commit_methods_and_conventions(exo):
    study, _, rec = exo
    meta = rec.static["meta"]
    assert meta["rerun_sdk_version"] == [rr.__version__]
    assert meta["methods"] == ["pinocchio", "noisy", "slow", "broken"]
    assert meta["methods_ok"] == ["pinocchio", "noisy"]
    assert meta["exo_bench_commit"][0] not in ("", None)
    assert "G^-T" in meta["conventions"][0] and "F_k" in meta["conventions"][0]
    text = meta["TextDocument:text"][0]
    assert "over the time budget of 1 s" in text and "RuntimeError: singular matrix" in text
    assert "joint moments" in text and rr.__version__ in text
    # the loads beside level walking, with the same numbers as the scene report's table
    from exo_bench.bench.studies.plausibility import plausibility

    p = plausibility(study)
    assert "## Loads" in text and "beside level walking" in text and "Not comparable with walking" in text
    for row in p.joints:
        assert f"- {row.joint}: {row.sagittal:.2f} N·m/kg sagittal" in text


def test_blueprint_lays_out_the_3d_view_and_time_series_of_recorded_entities(exo):
    study, path, rec = exo
    reader = RrdReader(path)
    [bp] = reader.blueprints()
    views = []
    for chunk in reader.stream(store=bp).to_chunks():
        rb = chunk.to_record_batch()
        if "ViewBlueprint:class_identifier" in rb.schema.names:
            views.append(
                (
                    rb.column("ViewBlueprint:class_identifier").to_pylist()[-1][0],
                    rb.column("ViewBlueprint:space_origin").to_pylist()[-1][0],
                )
            )
    kinds = defaultdict(list)
    for kind, origin in views:
        kinds[kind].append(origin)
    assert kinds["3D"] == ["world"]
    series = kinds["TimeSeries"]
    assert {"differences/moments", "differences/forces", "generalised"} <= set(series)
    assert any(o.startswith("moments/group1") for o in series) and any(o.startswith("forces/group1") for o in series)
    for origin in series:  # every plot shows something that was recorded
        assert any(e.startswith(origin + "/") for e in rec.temporal), origin
    groups = {e.rsplit("/", 1)[0] for e in rec.temporal if e.startswith(("moments/", "forces/"))}
    assert groups <= set(series)  # and every group has a plot


def test_the_rerun_executable_is_installed_with_rerun_sdk():
    """The checks below need it; it comes with the rerun-sdk dependency, so its absence is a broken install."""
    assert rerun_executable() is not None


@pytest.mark.parametrize("which", ["exo", "planar"])
def test_rerun_rrd_verify_accepts_the_recording(which, request):
    _, path, _ = request.getfixturevalue(which)
    assert "1 file verified without error" in verify_recording(path)


def test_verify_rejects_a_truncated_recording_and_a_non_recording(exo, tmp_path):
    _, path, _ = exo
    data = path.read_bytes()
    (tmp_path / "cut.rrd").write_bytes(data[: len(data) // 2])
    (tmp_path / "junk.rrd").write_bytes(b"not a recording")
    for bad in ("cut.rrd", "junk.rrd"):
        with pytest.raises(ValueError, match="rerun rrd verify failed"):
            verify_recording(tmp_path / bad)


# ----------------------------------------------------------------------------- writing
def test_a_failed_write_leaves_the_previous_recording_and_no_temporary_file(exo, tmp_path, monkeypatch):
    study, path, _ = exo
    target = tmp_path / "scene.rrd"
    target.write_bytes(path.read_bytes())
    before = target.read_bytes()

    def boom(self, *a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(rr.RecordingStream, "send_columns", boom)
    with pytest.raises(RuntimeError, match="disk full"):
        write_recording(study, target)
    assert target.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["scene.rrd"]


def test_a_recording_is_written_whole_with_ordinary_permissions(exo, tmp_path):
    study, _, _ = exo
    p = write_recording(study, tmp_path / "sub" / "x.rrd")
    assert sorted(os.listdir(p.parent)) == ["x.rrd"]
    mask = os.umask(0)
    os.umask(mask)
    assert (p.stat().st_mode & 0o777) == (0o666 & ~mask)
    assert RrdReader(p).store() is not None  # has its footer: the stream was closed before the rename


def test_a_scene_where_no_method_succeeded_still_records_the_motion_and_says_why(tmp_path):
    mech = fig2b(2)
    t = np.linspace(0.0, 1.0, 40, endpoint=False)
    study = Study(
        mech.name,
        mech,
        planar_gait(mech, t),
        "test gait",
        {"broken": MethodResult("broken", error="ValueError: no such method")},
        reference="broken",
    )
    rec = Recording(write_recording(study, tmp_path / "none.rrd"))
    assert "world/rods" in rec.temporal and not any(e.startswith("moments/") for e in rec.temporal)
    assert "ValueError: no such method" in rec.static["meta"]["TextDocument:text"][0]


# ----------------------------------------------------------------------------- viewer screenshot
def test_a_screenshot_needs_a_display_and_says_so(exo, tmp_path, monkeypatch):
    _, path, _ = exo
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(OSError, match="no display"):
        recording.screenshot(path, tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


@pytest.mark.skipif(
    not os.environ.get("EXO_BENCH_SCREENSHOT") or not os.environ.get("DISPLAY"),
    reason="slow (about 20 s on a CPU renderer) and needs a display: set EXO_BENCH_SCREENSHOT=1 "
    "and DISPLAY (e.g. Xvfb with mesa-vulkan-drivers)",
)
def test_the_viewer_renders_the_recording_with_its_layout(exo, tmp_path):
    from PIL import Image

    _, path, _ = exo
    png = recording.screenshot(path, tmp_path / "viewer.png", size="1280x720")
    img = np.asarray(Image.open(png).convert("L"), dtype=float)
    assert img.shape == (720, 1280)
    assert img.std() > 10  # not a blank (all-black) frame: the views were drawn


def test_a_method_returning_nan_is_named_in_the_recording(tmp_path):
    study = _study(fig2a(2), planar_gait, 30, noisy=False)
    bad = study.results["pinocchio"].tau.copy()
    bad[3:5, 0] = np.inf
    study.results["shaky"] = MethodResult("shaky", bad)
    rec = Recording(write_recording(study, tmp_path / "nan.rrd"))
    assert "WARNING: shaky returned 2 non-finite value(s) at 2 instant(s)" in rec.static["meta"]["TextDocument:text"][0]
