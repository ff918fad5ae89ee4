"""The compiled directional derivatives (models/newton_euler/products.py, issue 36): the JVP and VJP of
inverse dynamics by the O(n) passes in numba, serial and over threads, against the numpy reference of the
same formulas (models/newton_euler/products.py, which tests/test_jvp.py holds to the full Jacobians).

**Error model.** Both evaluate the same per-rod products and passes; their sines and cosines differ by an ulp
or two and their sums run in other orders, so they differ by the rounding of the Jacobian's entries times the
direction, the bound of tests/test_jvp.py: ``K eps sum_j D_ij |v_j|`` with ``D`` the scale of each entry's
differentiated terms (tests/test_derivatives_analytic.py's ``derivative_scales``, conftest's
``mass_matrix_scale``)."""

from __future__ import annotations

import numpy as np
import pytest
from test_derivatives_analytic import derivative_scales, states
from test_jvp import _directions, _mv, _vm

from conftest import assert_close, mass_matrix_scale
from exo_bench import presets
from exo_bench.models.derivatives import Derivatives
from exo_bench.models.newton_euler import products as pc
from exo_bench.models.mechanism.presets import random_tree

TREES = [random_tree(7, 2, 22), random_tree(9, 3, 23), presets.exo5(dim=3)]


@pytest.mark.parametrize("mech", TREES, ids=[m.name for m in TREES])
def test_compiled_products_equal_the_numpy_reference(mech):
    """Serial and parallel drivers, JVP and VJP, on seeded random trees in 2D and 3D with branch signs."""
    D = Derivatives(mech, kernel="numba")
    q, qd, qdd = states(mech, 6, 51)
    dq, dqd, dqdd, w = _directions(mech, 6, 52)
    sq, sqd = derivative_scales(mech, q, qd, qdd)
    sm = mass_matrix_scale(mech, q)
    args = (D.tree, D.table, mech.dim, float(mech.g), q, qd, qdd)
    ref = pc.jvp(*args, dq, dqd, dqdd, reference=True)
    scale = _mv(sq, np.abs(dq)) + _mv(sqd, np.abs(dqd)) + _mv(sm, np.abs(dqdd))
    par = np.empty_like(ref)
    pc.products_parallel(D.table, float(mech.g), mech.dim, q, qd, qdd, dq, dqd, dqdd, par, par, par, False)
    for name, got in (("serial", pc.jvp(*args, dq, dqd, dqdd)), ("parallel", par)):
        assert_close(got, ref, scale, what=f"{mech.name} jvp {name}")
    refs = pc.vjp(*args, w, reference=True)
    pars = tuple(np.empty_like(r) for r in refs)
    pc.products_parallel(D.table, float(mech.g), mech.dim, q, qd, qdd, w, w, w, *pars, True)
    for name, gots in (("serial", pc.vjp(*args, w)), ("parallel", pars)):
        for what, got, r, s in zip(("w dtau/dq", "w dtau/dqd", "w M"), gots, refs, (sq, sqd, sm)):
            assert_close(got, r, _vm(np.abs(w), s), what=f"{mech.name} vjp {name} {what}")


def test_the_provider_runs_the_compiled_products_and_they_mean_something():
    """``model.derivatives``' products with the compiled kernel equal those of its numpy reference (the
    option ``kernel``), and a JVP along a unit direction is a column of the full Jacobian: nonzero."""
    mech = random_tree(6, 3, 21)
    q, qd, qdd = states(mech, 3, 53)
    dq, dqd, dqdd, w = _directions(mech, 3, 54)
    fast, ref = Derivatives(mech, kernel="numba"), Derivatives(mech, kernel="numpy")
    sq, sqd = derivative_scales(mech, q, qd, qdd)
    scale = _mv(sq, np.abs(dq)) + _mv(sqd, np.abs(dqd)) + _mv(mass_matrix_scale(mech, q), np.abs(dqdd))
    assert_close(
        fast.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd), ref.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd), scale
    )
    e = np.zeros_like(q)
    e[:, 2] = 1.0
    jq = fast.inverse_dynamics(q, qd, qdd)[0]
    col = fast.inverse_dynamics_jvp(q, qd, qdd, e, 0 * e, 0 * e)
    assert np.abs(col).max() > 0.1
    assert_close(col, jq[:, :, 2], sq[:, :, 2])
