"""The plausibility section of the scene reports: the peaks it states are the physics of the motion,
beside Winter's numbers, and it says where the model cannot be compared with walking."""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.bench.studies.plausibility import markdown, plausibility, text
from exo_bench.bench.studies.study import MethodResult, Study, run_methods
from exo_bench.models.states.states import split
from exo_bench.models.gait.motion import PAPER_ASSUMED_V1, GaitParams, gait, planar_gait
from exo_bench.models.gait.normative import WINTER
from exo_bench.models.engines.pinocchio_backend import build_model, joint_torques
from exo_bench.models.mechanism.presets import exo5, fig2a, fig5


def _study(mech, fn, params=GaitParams(), samples=200):
    t = np.arange(samples) * (params.T / samples)
    return run_methods(mech.name, mech, fn(mech, t, params), "test gait", ["pinocchio"])


@pytest.fixture(scope="module")
def planar():
    return _study(fig5(2), planar_gait)


def test_planar_joint_moments_per_kg_are_pinocchios_joint_torques(planar):
    """In 2D a joint's relative angle turns its whole subtree, so its joint torque is the net joint
    moment: the table's peaks are Pinocchio's, divided by the model's mass."""
    mech, mo = planar.mechanism, planar.motion
    tj = joint_torques(mech, mo.q, mo.qd, mo.qdd)
    names = build_model(mech).joint_names
    p = plausibility(planar)
    for row in p.joints:
        expected = np.abs(tj[:, names.index(f"L{row.link + 1}_phi")]).max() / mech.total_mass
        assert row.sagittal == pytest.approx(expected, rel=1e-12)
        assert row.magnitude == row.sagittal


def test_rod_forces_are_the_length_rows_of_tau_in_body_weights(planar):
    mech = planar.mechanism
    _, _, rods = split(mech, planar.results["pinocchio"].tau)
    p = plausibility(planar)
    np.testing.assert_allclose(
        [r.force for r in p.rods], np.abs(rods).max(axis=0) / (mech.total_mass * mech.g), rtol=1e-15
    )


def test_the_exoskeletons_joints_get_winters_values_and_the_verdicts():
    p = plausibility(_study(exo5(3), gait))
    by_joint = {r.joint: r for r in p.joints}
    assert by_joint["stance ankle (support point O)"].normative == WINTER.moments["ankle, stance"]
    assert by_joint["swing knee"].normative == WINTER.moments["knee, swing"]
    assert by_joint["stance knee"].meaning.startswith("no:")
    assert p.walker and p.rods[4].normative is None
    md = markdown(p)
    assert "| stance ankle (support point O) | " in md and "Table A.5 ankle moment 89.8 N·m" in md
    for needle in (
        "**No feet.**",
        "**No double support.**",
        "**A periodic single-support phase.**",
        "not comparable with walking",
        "namita-kumar/WinterWalkingData",
    ):
        assert needle in md
    assert "stance ankle (support point O)" in text(p) and "Not comparable with walking" in text(p)


def test_the_hip_travel_of_the_paper_assumed_gait_is_the_rocking_of_issue_17():
    """The old gait: the hip rocks forward and back by +-0.27 m over the support point."""
    p = plausibility(_study(exo5(3), gait, PAPER_ASSUMED_V1))
    assert p.hip_travel == pytest.approx(2 * 0.2697, abs=1e-3)
    assert f"The hip moves {p.hip_travel:.2f} m forward and back over O" in markdown(p)


def test_a_mechanism_that_is_not_the_exoskeleton_gets_no_normative_values():
    p = plausibility(_study(fig2a(2), planar_gait))
    assert not p.walker and all(r.normative is None for r in p.joints + p.rods)
    assert "no joint has a normative value" in markdown(p)
    assert "level walking" not in text(p)


def test_no_table_when_no_method_ran():
    mech = fig2a(2)
    t = np.linspace(0, 1, 5)
    st = Study("s", mech, planar_gait(mech, t), "m", {"x": MethodResult("x", error="boom")}, reference="x")
    assert plausibility(st) is None
