"""States in any memory order give the same forces: a transposed (Fortran-ordered) batch, e.g. the columns of
a CasADi or Fortran result, once gave the compiled matrix kernels wrong forces silently (860 N off on exo5).
The validated edge (``models.mechanism.as_states``) now hands the kernels C-ordered arrays."""

import numpy as np
import pytest

from conftest import assert_forces_agree
from exo_bench.api import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("method", ["matrix", "matrix-factored", "recurrence"])
def test_fortran_ordered_states_give_the_same_forces(dim, method):
    mech = exo5(dim)
    q, qd, qdd = random_states(mech, 40, seed=5)
    ref = prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)
    model = prepare(mech, method)
    tau = model.inverse_dynamics(*(np.asfortranarray(x) for x in (q, qd, qdd)))
    assert_forces_agree(tau, ref, mech, q, qd, qdd, what=f"{method}, Fortran-ordered states")
    M = model.mass_matrix(np.asfortranarray(q))
    np.testing.assert_allclose(M, model.mass_matrix(q), rtol=0, atol=0)
