"""A Mechanism is immutable, its numpy views included (issue 34, W6).

Every method reads the mechanism's arrays, some once when it is prepared and some at every call:
a write into ``mass_array``, ``fractions`` or ``sign_array`` used to change recurrence and newton-euler
but not the others, so a prepared recurrence model's ``mass_matrix`` disagreed with its own
``inverse_dynamics``."""

import numpy as np
import pytest
from conftest import assert_forces_agree, installed_methods

from exo_bench import prepare
from exo_bench.models.engines.joint_coordinates import joint_basis
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, random_tree


def _arrays(mech) -> dict[str, np.ndarray]:
    """Every numpy array a Mechanism exposes as an attribute (found, not listed, so a new one is covered)."""
    out = {}
    for name in dir(type(mech)):
        if name.startswith("_"):
            continue
        value = getattr(mech, name)
        if isinstance(value, np.ndarray):
            out[name] = value
    return out


@pytest.mark.case("W6")
@pytest.mark.parametrize("mech", [exo5(2), exo5(3), random_tree(7, 3, 5)], ids=["exo5-2d", "exo5-3d", "tree7-3d"])
def test_every_array_a_mechanism_exposes_is_read_only(mech):
    """Every numpy array a Mechanism exposes (mass_array, fractions, sign_array, ancestor_or_self, ...) and its
    cached joint map are read-only: a write raises ValueError and changes nothing."""
    arrays = _arrays(mech)
    assert {"mass_array", "fractions", "sign_array"} <= set(arrays)
    for name, a in arrays.items():
        before = a.copy()
        with pytest.raises(ValueError, match="read-only"):
            a.flat[0] = 123.0
        with pytest.raises(ValueError):
            a.flags.writeable = True  # it owns its data: the flag cannot be set back
        assert np.array_equal(getattr(mech, name), before), name
    with pytest.raises(ValueError, match="read-only"):
        joint_basis(mech).G_inv[0, 0] = 5.0


@pytest.mark.case("W6")
def test_every_method_agrees_on_a_mechanism_whose_arrays_a_user_tried_to_change():
    """A model prepared before and one prepared after an attempted write agree with Pinocchio within the
    error model, for every installed method, and recurrence's mass matrix stays that of its own inverse
    dynamics."""
    mech = exo5(3)
    q, qd, qdd = random_states(mech, 3, 11)
    before = {m: prepare(mech, m) for m in installed_methods() if m != "matrix-paper"}
    for a in (mech.mass_array, mech.fractions, mech.sign_array):
        with pytest.raises(ValueError):
            a *= 3.0
    ref = prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)
    for name, model in before.items():
        assert_forces_agree(model.inverse_dynamics(q, qd, qdd), ref, mech, q, qd, qdd, what=name)
        assert_forces_agree(prepare(mech, name).inverse_dynamics(q, qd, qdd), ref, mech, q, qd, qdd, what=name)
    rec = before["recurrence"]
    M, h = rec.mass_matrix(q), rec.bias_forces(q, qd)
    assert_forces_agree(np.einsum("sij,sj->si", M, qdd) + h, ref, mech, q, qd, qdd, k=16, what="M qdd + h")
