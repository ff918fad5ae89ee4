"""The figures: the physics of the joint moments they show, and their content (not their pixels)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from matplotlib.collections import PathCollection
from matplotlib.figure import Figure

from exo_bench.bench.output.figures import scene_figures as plots
from exo_bench.bench.output.figures.curves import differences_figure, forces_figure, group_by_scale, moments_figure
from exo_bench.bench.output.figures.palette import method_color
from exo_bench.bench.output.figures.scene_figures import kinogram_figure, write_plots
from exo_bench.bench.output.provenance import save_figure
from exo_bench.models.engines.joint_coordinates import (
    force_labels,
    joint_basis,
    joint_quantities,
    moment_labels,
    moments_and_forces,
)
from exo_bench.bench.studies.study import MethodResult, Study, run_methods
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.states.states import split
from exo_bench.models.gait.motion import GaitParams, gait, planar_gait, random_states
from exo_bench.models.engines.pinocchio_backend import build_model, inverse_dynamics, joint_torques
from exo_bench.models.mechanism.presets import exo5, fig2b, fig5, random_tree


def _study(mech, motion_fn, samples=120, noisy=False) -> Study:
    t = np.linspace(0.0, GaitParams().T, samples, endpoint=False)
    study = run_methods(mech.name, mech, motion_fn(mech, t), "test gait", ["pinocchio"])
    if noisy:
        ref = study.results["pinocchio"].tau
        study.results["noisy"] = MethodResult("noisy", ref + 1e-6 * np.random.default_rng(3).standard_normal(ref.shape))
        study.results["broken"] = MethodResult("broken", error="RuntimeError: boom")
    return study


@pytest.fixture(scope="module")
def exo():
    return _study(exo5(3), gait, noisy=True)


@pytest.fixture(scope="module")
def planar():
    return _study(fig5(2), planar_gait)


# ----------------------------------------------------------------------------- the moments shown
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("dim", [2, 3])
def test_joint_moments_from_the_paper_tau_equal_rnea_in_joint_coordinates(seed, dim):
    """G^-T applied to the generalised forces of the absolute angles gives Pinocchio's joint torques
    computed directly in its joint coordinates, on random trees with reversed links."""
    mech = random_tree(5, dim, seed)
    q, qd, qdd = random_states(mech, 20, seed)
    tau = inverse_dynamics(mech, q, qd, qdd)
    tj = joint_torques(mech, q, qd, qdd)
    scale = np.abs(tj).max()
    assert np.abs(joint_quantities(mech, tau) - tj).max() <= 1e-11 * scale


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("dim", [2, 3])
def test_joint_and_absolute_coordinates_deliver_the_same_power(seed, dim):
    """Virtual work is coordinate-free: tau_joint . qd_joint = tau . qd (qd_joint = G qd)."""
    mech = random_tree(6, dim, seed + 10)
    q, qd, qdd = random_states(mech, 15, seed)
    tau = inverse_dynamics(mech, q, qd, qdd)
    G = build_model(mech).G
    p_abs = np.einsum("sd,sd->s", tau, qd)
    p_joint = np.einsum("sd,sd->s", joint_quantities(mech, tau), qd @ G.T)
    np.testing.assert_allclose(p_joint, p_abs, rtol=1e-10, atol=1e-10 * np.abs(p_abs).max())


@pytest.mark.parametrize("dim", [2, 3])
def test_rod_forces_are_the_same_in_joint_and_absolute_coordinates(dim):
    """l_k maps to itself (its column of G is a unit vector), so F_k = tau[l_k] exactly."""
    mech = random_tree(7, dim, 4)
    q, qd, qdd = random_states(mech, 10, 1)
    tau = inverse_dynamics(mech, q, qd, qdd)
    _, _, l_block = split(mech, tau)
    np.testing.assert_array_equal(moments_and_forces(mech, tau)[1], l_block)
    jb = joint_basis(mech)
    assert [jb.labels[r] for r in jb.force_rows] == [f"F{k + 1} {mech.names[k]}" for k in range(mech.nlinks)]


def test_moment_rows_are_every_revolute_joint_once():
    mech = exo5(3)
    jb = joint_basis(mech)
    names = [jb.names[r] for r in jb.moment_rows]
    assert sorted(names) == sorted(f"L{k}_{a}" for k in range(1, 6) for a in ("phi", "psi"))


# ----------------------------------------------------------------------------- grouping by scale
@pytest.mark.parametrize("seed", range(20))
def test_grouping_by_scale_keeps_each_panel_within_the_ratio_and_cuts_at_the_widest_gaps(seed):
    rng = np.random.default_rng(seed)
    maxima = 10 ** rng.uniform(-2, 3, rng.integers(1, 16))
    if seed % 3 == 0:
        maxima[0] = 0.0  # a curve that is zero throughout
    g = group_by_scale(maxima, ratio=10.0)
    flat = [i for grp in g.groups for i in grp]
    assert sorted(flat + list(g.zero)) == list(range(len(maxima)))  # every curve exactly once
    assert all(maxima[i] == 0.0 for i in g.zero) and all(maxima[i] > 0 for i in flat)
    assert all(maxima[a] >= maxima[b] for a, b in zip(flat, flat[1:]))  # largest scale first
    for grp in g.groups:
        assert maxima[grp[0]] <= 10.0 * maxima[grp[-1]]  # a panel spans at most 10x
    for a, b in zip(g.groups, g.groups[1:]):
        cut = maxima[a[-1]] / maxima[b[0]]
        inner = [maxima[x] / maxima[y] for grp in (a, b) for x, y in zip(grp, grp[1:])]
        assert all(cut >= r for r in inner)  # boundaries at the widest gaps


def test_grouping_keeps_curves_of_similar_size_together():
    g = group_by_scale([470.0, 428.0, 51.0, 49.0, 1.3, 0.0])
    assert g.groups[0][:2] == (0, 1) and {2, 3} <= set(sum(g.groups, ())) and g.zero == (5,)
    assert any({2, 3} <= set(grp) for grp in g.groups)


def test_grouping_rejects_bad_input_with_a_clear_message():
    with pytest.raises(ValueError, match="maxima"):
        group_by_scale([1.0, np.nan])
    with pytest.raises(ValueError, match="ratio"):
        group_by_scale([1.0], ratio=1.0)


# ----------------------------------------------------------------------------- Figs. 7 and 8
def _lines_by_panel(fig: Figure):
    out = []
    for ax in fig.axes:
        lines = [ln for ln in ax.get_lines() if ln.get_gid()]
        if lines:
            out.append((ax, lines))
    return out


def _notes(fig) -> str:
    return " ".join(t.get_text() for ax in fig.axes for t in ax.texts)


def _zero_named(fig, labels) -> list[str]:
    """The curves the figure's notes name as zero throughout."""
    notes = _notes(fig)
    if "zero throughout" not in notes:
        return []
    named = notes.split("zero throughout", 1)[1].split(":", 1)[1].split("\n")[0]
    return [x.strip() for x in named.split(",") if x.strip() in labels]


@pytest.mark.parametrize(
    "kind", ["forces"]
)  # the moments figure shows net joint moments: tests/test_figure_conventions.py
@pytest.mark.parametrize("which", ["exo", "planar"])
def test_each_curve_sits_in_the_panel_of_its_scale(kind, which, request):
    """Read from what is drawn: every panel's reference curves are the study's arrays, span at most
    the ratio of their maxima, and every curve is drawn in exactly one panel or named as zero."""
    study = request.getfixturevalue(which)
    fig = (moments_figure if kind == "moments" else forces_figure)(study)
    mech = study.mechanism
    values = moments_and_forces(mech, study.results["pinocchio"].tau)[0 if kind == "moments" else 1]
    labels = moment_labels(mech) if kind == "moments" else force_labels(mech)
    panels = _lines_by_panel(fig)
    seen = []
    for ax, lines in panels:
        ref_lines = [ln for ln in lines if ln.get_gid().startswith("pinocchio:")]
        maxima = [np.abs(ln.get_ydata()).max() for ln in ref_lines]
        assert max(maxima) <= 10.0 * min(maxima)
        for ln in ref_lines:  # the curve is the study's array
            j = labels.index(ln.get_gid().split(":", 1)[1])
            np.testing.assert_array_equal(ln.get_ydata(), values[:, j])
            seen.append(j)
        lo, hi = min(maxima), max(maxima)
        assert f"{hi:.3g}" in ax.get_title(loc="left") and f"{lo:.3g}" in ax.get_title(loc="left")
    zero = [labels.index(x) for x in _zero_named(fig, labels)]
    assert sorted(seen + zero) == list(range(len(labels)))
    for a, b in zip(panels, panels[1:]):  # larger scales above smaller ones
        assert min(np.abs(ln.get_ydata()).max() for ln in a[1]) > max(np.abs(ln.get_ydata()).max() for ln in b[1])


def test_titles_say_model_motion_methods_and_which_quantity(exo, planar):
    fig = moments_figure(exo)
    title = fig._suptitle.get_text()
    assert "exo5-3d" in title and "test gait" in title and "Fig. 7" in title
    assert "Net joint moments" in title and "N·m/kg" in title and "not the generalised forces" in title
    notes = " ".join(t.get_text() for ax in fig.axes for t in ax.texts)
    assert "broken: failed (RuntimeError: boom)" in notes
    notes = " ".join(t.get_text() for ax in forces_figure(exo).axes for t in ax.texts)
    assert "pinocchio (solid)" in notes and "noisy (dashed)" in notes and "broken: failed (RuntimeError: boom)" in notes
    ftitle = forces_figure(planar)._suptitle.get_text()
    assert "fig5-2d" in ftitle and "Fig. 8" in ftitle and "the same in joint and in absolute coordinates" in ftitle
    for fig in (moments_figure(planar), forces_figure(planar)):
        assert fig.axes[-1].get_xlabel() == "time t (s)" or any(ax.get_xlabel() == "time t (s)" for ax in fig.axes)
        units = {ax.get_ylabel() for ax in fig.axes if ax.get_ylabel()}
        assert units in ({"M / m (N·m/kg)"}, {"F (N)"})


def test_every_method_is_drawn_and_a_failed_one_is_named(exo):
    fig = forces_figure(exo)
    gids = [ln.get_gid() for _, lines in _lines_by_panel(fig) for ln in lines]
    labels = force_labels(exo.mechanism)
    n = len(labels) - len(_zero_named(fig, labels))
    assert sum(g.startswith("pinocchio:") for g in gids) == n
    assert sum(g.startswith("noisy:") for g in gids) == n
    assert not any(g.startswith("broken:") for g in gids)


def test_differences_figure_shows_the_largest_joint_difference_and_needs_two_methods(exo, planar):
    assert differences_figure(planar) is None
    fig = differences_figure(exo)
    mech = exo.mechanism
    d = exo.results["noisy"].tau - exo.results["pinocchio"].tau
    dm, df = moments_and_forces(mech, d)
    lines = [ax.get_lines() for ax in fig.axes if ax.get_lines()]
    np.testing.assert_allclose(lines[0][0].get_ydata(), np.abs(dm).max(axis=1))
    np.testing.assert_allclose(lines[1][0].get_ydata(), np.abs(df).max(axis=1))
    legend = [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]
    assert any(x.startswith("noisy − pinocchio: max ") and "of the largest pinocchio value" in x for x in legend)
    assert "method − pinocchio" in fig._suptitle.get_text()


def test_a_study_without_results_cannot_be_plotted_and_says_why():
    mech = fig2b(2)
    t = np.linspace(0, 1, 10)
    study = Study("s", mech, planar_gait(mech, t), "m", {"x": MethodResult("x", skipped="over budget")})
    with pytest.raises(ValueError, match="no method produced tau.*over budget"):
        moments_figure(study)


# ----------------------------------------------------------------------------- kinogram (Fig. 9)
def _masses_collections(fig):
    return {
        c.get_gid(): c
        for ax in fig.axes
        for c in ax.collections
        if isinstance(c, PathCollection) and (c.get_gid() or "").startswith("masses:")
    }


def _frame_times(fig) -> list[float]:
    """The times the frame panels' titles give ("frame k\nt = 0.12 s")."""
    out = []
    for ax in fig.axes:
        title = ax.get_title()
        if title.startswith("frame "):
            out.append(float(title.split("t = ")[1].split(" s")[0]))
    return out


@pytest.mark.parametrize("which", ["exo", "planar"])
def test_kinogram_frames_are_drawn_in_place_with_dots_of_area_proportional_to_mass(which, request):
    """Every frame, overlaid and one per panel, sits where the kinematics puts it: no shift."""
    study = request.getfixturevalue(which)
    mech = study.mechanism
    fig = kinogram_figure(study, frames=7)
    idx = plots.kinogram_frames(study, 7)  # evenly spread, first and last sample
    assert len(idx) == 7 and idx[0] == 0 and idx[-1] == len(study.motion.t) - 1
    np.testing.assert_allclose(study.motion.t[idx], _frame_times(fig), atol=0.005 + 1e-12)
    P = point_mass_positions(mech, study.motion.q[idx])  # (F, n, 3, dim)
    cols = _masses_collections(fig)
    projections = plots.projections(mech)
    assert len(cols) == 7 * (len(projections) + 1)  # overlays + one panel per frame
    m = mech.mass_array.reshape(-1)
    for k in range(7):
        for gid, proj in [(f"masses:frame:{k}", projections[0])] + [
            (f"masses:overlay:{p.name}:{k}", p) for p in projections
        ]:
            col = cols[gid]
            sizes = np.asarray(col.get_sizes())
            np.testing.assert_allclose(sizes / m, (sizes / m)[0])  # area ∝ mass
            hx, vx = proj.axes
            expected = np.stack([P[k, :, :, hx].reshape(-1), P[k, :, :, vx].reshape(-1)], axis=1)
            np.testing.assert_allclose(col.get_offsets(), expected, atol=1e-12)


def test_kinogram_draws_every_rod_of_every_frame_from_start_to_end_and_the_support_at_the_origin(planar):
    mech = planar.mechanism
    fig = kinogram_figure(planar, frames=4)
    idx = plots.kinogram_frames(planar, 4)
    P = point_mass_positions(mech, planar.motion.q[idx])
    rods = {ln.get_gid(): ln for ax in fig.axes for ln in ax.get_lines() if (ln.get_gid() or "").startswith("rod:")}
    for k in range(4):
        for i in range(mech.nlinks):
            ln = rods[f"rod:frame:{k}:{i}"]
            np.testing.assert_allclose(ln.get_xdata(), [P[k, i, 0, 0], P[k, i, 2, 0]])
            np.testing.assert_allclose(ln.get_ydata(), [P[k, i, 0, 1], P[k, i, 2, 1]])
    supports = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_gid() == "support"]
    assert supports and all(list(ln.get_xdata()) == [0.0] and list(ln.get_ydata()) == [0.0] for ln in supports)
    floors = [ln for ax in fig.axes for ln in ax.get_lines() if ln.get_gid() == "floor"]
    assert floors and all(set(ln.get_ydata()) == {0.0} for ln in floors)


def test_the_shipped_gaits_kinogram_shows_no_swing_leg_point_below_the_floor():
    from exo_bench.bench.studies.scenes import load_scene

    sc = load_scene("exo5-3d")
    study = run_methods(sc.name, sc.mechanism, sc.build_motion(), sc.motion_label(), ["pinocchio"])
    fig = kinogram_figure(study)
    swing = [3 * i + b for i in (2, 3) for b in range(3)]  # the dots of links 3 and 4
    for gid, col in _masses_collections(fig).items():
        if gid.startswith("masses:frame:") or "sagittal" in gid:
            assert np.asarray(col.get_offsets())[swing, 1].min() >= 0.0, gid


def test_kinogram_of_a_3d_model_has_sagittal_and_frontal_views_and_says_it_is_drawn_in_place(exo, planar):
    fig = kinogram_figure(exo)
    title = fig._suptitle.get_text()
    assert "exo5-3d" in title and "Fig. 9" in title and "area ∝ point mass" in title
    assert "drawn in place" in title and "frames are not shifted" in title
    titles = [ax.get_title(loc="left") for ax in fig.axes]
    assert "sagittal (x–z)" in titles and "frontal (y–z)" in titles
    labels = {ax.get_xlabel() for ax in fig.axes} | {ax.get_ylabel() for ax in fig.axes}
    assert not any("walking" in x or "shifted" in x for x in labels)
    assert "x–y plane" in [ax.get_title(loc="left") for ax in kinogram_figure(planar).axes]


# ----------------------------------------------------------------------------- files
def test_figures_are_written_as_png_atomically(planar, tmp_path, monkeypatch):
    paths = write_plots(planar, tmp_path)
    assert [p.name for p in paths] == ["fig5-2d-moments.png", "fig5-2d-forces.png", "fig5-2d-kinogram.png"]
    for p in paths:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    before = paths[0].read_bytes()

    def boom(self, *a, **k):
        raise RuntimeError("renderer died")

    monkeypatch.setattr(Figure, "savefig", boom)
    with pytest.raises(RuntimeError, match="renderer died"):
        save_figure(moments_figure(planar), paths[0])
    assert paths[0].read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == sorted(p.name for p in paths)


def test_two_methods_add_the_differences_figure(exo, tmp_path):
    names = [p.name for p in write_plots(exo, tmp_path, frames=3)]
    assert names[-1] == "exo5-3d-differences.png" and len(names) == 4
    fig = differences_figure(exo)
    colours = {ln.get_gid(): ln.get_color() for ax in fig.axes for ln in ax.get_lines() if ln.get_gid()}
    assert colours["diff:noisy"] == method_color("noisy", ["pinocchio", "noisy"])


def test_a_method_returning_nan_is_reported_not_hidden(planar):
    ref = planar.results["pinocchio"].tau
    bad = ref.copy()
    bad[5, 2] = np.nan
    study = Study(
        planar.name,
        planar.mechanism,
        planar.motion,
        planar.motion_label,
        {"pinocchio": planar.results["pinocchio"], "shaky": MethodResult("shaky", bad)},
    )
    t5 = f"{planar.motion.t[5]:.4g}"
    for fig in (moments_figure(study), forces_figure(study), differences_figure(study)):
        notes = " ".join(t.get_text() for ax in fig.axes for t in ax.texts)
        assert f"WARNING: shaky returned 1 non-finite value(s) at 1 instant(s), first at t = {t5} s" in notes
