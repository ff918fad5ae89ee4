"""A scene's external forces (issue 37): the human-2d-stride scene supplies the stored stride's floor
contact forces as ``f_ext`` per sample (bench/studies/scene_motion.py), so every method's inverse dynamics
in its methods table includes the floor and equals the optimiser's loads; scenes of other motions supply
none.

Oracles: the stored stride's contact forces placed by name (:data:`exo_bench.bench.studies.stride.data.CONTACTS`,
heel and toe end points) and the optimiser's loads (its stored ``tau``, CasADi's). Error model: that of
tests/test_stride.py (conftest's ``term_scale`` plus the external forces' terms, widened by the contact
forces' own rounding, :func:`test_stride.contact_rounding`): the stored contact forces are the numpy ones
to that rounding, and the optimiser's loads were computed with its own."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import K, assert_close, term_scale
from test_external_forces import external_force_scale
from test_stride import contact_rounding

from exo_bench.bench.studies.scene_run import run_scene
from exo_bench.bench.studies.scenes import SHIPPED, load_scene
from exo_bench.bench.studies.stride import data
from exo_bench.bench.studies.study import run_methods

METHODS = ("newton-euler", "matrix-factored", "pinocchio")


@pytest.fixture(scope="module")
def scene():
    return load_scene(SHIPPED / "human-2d-stride.toml")


def test_the_stride_scene_supplies_its_contact_forces_at_the_heel_and_toe_points(scene):
    forces = scene.external_forces()
    st, mech = scene.motion["stored"], scene.mechanism
    assert forces is not None and forces.f_ext.shape == (len(st.t), mech.nlinks, 3, mech.dim)
    for j, (point, link) in enumerate(data.CONTACTS):
        assert st.contact_names[j] == point
        np.testing.assert_array_equal(forces.f_ext[:, mech.names.index(link), 2], st.contact[:, j])
    placed = np.zeros(forces.f_ext.shape[1:3], dtype=bool)
    placed[[mech.names.index(link) for _, link in data.CONTACTS], 2] = True
    assert not forces.f_ext[:, ~placed].any()  # nothing anywhere else
    # the floor carries the body: the vertical forces' mean over the stride is its weight (no net lift)
    assert abs(forces.f_ext[..., 1].sum(axis=(1, 2)).mean() / st.body_weight - 1) < 0.02
    np.testing.assert_array_equal(forces.expected, st.tau)


def test_a_scene_without_external_forces_supplies_none():
    assert load_scene(SHIPPED / "exo5-2d.toml").external_forces() is None


def test_every_method_in_the_scene_includes_the_floor_and_equals_the_optimisers_loads(scene):
    st, mech = scene.motion["stored"], scene.mechanism
    forces = scene.external_forces()
    study = run_methods(
        scene.name, mech, scene.build_motion(), "", list(METHODS), reference=METHODS[0], f_ext=forces.f_ext
    )
    scale = term_scale(mech, st.q, st.qd, st.qdd) + external_force_scale(mech, st.q, forces.f_ext)
    scale = scale + external_force_scale(mech, st.q, contact_rounding(st.q, st.qd)) / K
    for m in METHODS:
        assert study.results[m].ok, (m, study.results[m].error)
        assert_close(study.tau(m), st.tau, scale, K, f"{m}: the scene's loads along the stride")
    # without the floor the root's length row carries the body's weight instead: the check can fail
    bare = run_methods(scene.name, mech, scene.build_motion(), "", [METHODS[0]], reference=METHODS[0])
    root = mech.nlinks + mech.names.index("root")
    assert np.abs(bare.tau(METHODS[0])[:, root]).max() > 0.5 * st.body_weight


def test_the_scenes_table_says_the_floor_is_in_and_how_far_from_the_optimiser(scene, tmp_path):
    small = dataclasses.replace(scene, methods=METHODS[:2], reference=METHODS[0], outputs=("table",))
    small.motion.update(scene.motion)  # the motion dict is not copied by replace: same stored stride
    o = run_scene(small, tmp_path)
    text = (tmp_path / f"{scene.name}.md").read_text()
    assert "without the floor's force" not in text
    note = next(n for n in o.notes if n.startswith("External forces"))
    assert "optimiser's loads" in note and "heel and toe" in note
    worst = float(note.split("largest difference ")[1].split(" ")[0])
    assert worst < 1e-9, note
