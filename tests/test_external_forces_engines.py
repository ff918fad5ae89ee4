"""External forces (``f_ext``, issue 37) against the three engines' own: Pinocchio's ``rnea(..., fext)``,
MuJoCo's ``xfrc_applied``, Drake's applied spatial forces (``MultibodyForces`` in
``CalcInverseDynamics``), each reached through the method's public call with ``f_ext``; on seeded
random trees in 2D and 3D, to the error model of tests/test_external_forces.py (its
:func:`external_force_scale` added to conftest's term scale, MuJoCo's com-frame term too)."""

from __future__ import annotations

import pytest
from conftest import K, assert_close, com_frame_scale, term_scale
from test_external_forces import TREES, _case, external_force_scale

from exo_bench import prepare


def _reference(mech, q, qd, qdd, f):
    """Newton-Euler's numpy passes minus Q (the numpy form)."""
    return prepare(mech, "newton-euler", kernel="numpy").inverse_dynamics(q, qd, qdd, f_ext=f)


def _against(method, mech, com_frame=False):
    model = prepare(mech, method)
    q, qd, qdd, f = _case(mech, 21, 3)
    got = model.inverse_dynamics(q, qd, qdd, f_ext=f)
    scale = term_scale(mech, q, qd, qdd) + external_force_scale(mech, q, f)
    if com_frame:
        scale = scale + com_frame_scale(mech, q, qd, qdd)
    ratio = assert_close(got, _reference(mech, q, qd, qdd, f), scale, K, f"{method} with f_ext")
    # Q alone, at rest and without gravity's part: the engine's own mapping of the forces
    Q = model._external_forces(q, f)
    ours = prepare(mech, "newton-euler")._external_forces(q, f)
    sc = external_force_scale(mech, q, f) + term_scale(mech, q)  # the engines' rounding at their own joints
    assert_close(Q, ours, sc + (com_frame_scale(mech, q) if com_frame else 0.0), K, f"{method}: Q")
    return ratio


#: Link 2 of a tree with no middle mass: no body there in any engine, its force is split.
HOLLOW = [
    m.replace(masses=tuple((a, 0.0, c) if i == 1 else (a, b, c) for i, (a, b, c) in enumerate(m.masses)))
    for m in TREES[1:3]
]
CASES = TREES + HOLLOW


@pytest.mark.parametrize("mech", CASES, ids=lambda m: m.name + ("-hollow" if m.masses[1][1] == 0 else ""))
def test_pinocchio_fext_agrees(mech):
    _against("pinocchio", mech)


@pytest.mark.parametrize("mech", CASES, ids=lambda m: m.name + ("-hollow" if m.masses[1][1] == 0 else ""))
def test_mujoco_xfrc_applied_agrees(mech):
    pytest.importorskip("mujoco")
    _against("mujoco", mech, com_frame=True)


@pytest.mark.parametrize("mech", CASES, ids=lambda m: m.name + ("-hollow" if m.masses[1][1] == 0 else ""))
def test_drake_applied_spatial_forces_agree(mech):
    pytest.importorskip("pydrake")
    _against("drake", mech)
