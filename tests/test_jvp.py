"""Directional derivatives (issue 36): Jacobian-vector and vector-Jacobian products of inverse and forward
dynamics, ``model.derivatives.*_jvp`` / ``*_vjp`` (models/newton_euler/products.py), O(n) per sample.

Oracle: the full Jacobians of the same provider, ``J v`` and ``w^T J``, on seeded random trees in 2D and 3D
with branch signs. **Error model.** In exact arithmetic the two are equal; in float64 both sum the same
per-rod products in other orders, so they differ by the rounding of the Jacobian's entries times the
direction: ``|a - b| <= K eps sum_j D_ij |v_j|`` (and ``sum_i |w_i| D_ij`` for a VJP), with ``D`` the scale of
the differentiated terms of each entry from the mechanism and the states alone
(tests/test_derivatives_analytic.py's ``derivative_scales`` for ``dtau/dq`` and ``dtau/dqd``, conftest's
``mass_matrix_scale`` for ``M``). Forward dynamics adds a solve with ``M``: its products are held to the
perturbation bound of a linear system, ``2 K eps cond(M) |J| |v|`` per sample in 2-norms.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_derivatives_analytic import derivative_scales, states

from conftest import EPS, K, assert_close, mass_matrix_scale
from exo_bench import prepare, presets
from exo_bench.models.derivatives import Derivatives
from exo_bench.models.mechanism.presets import random_tree

TREES = [random_tree(6, 3, 21), random_tree(7, 2, 22), presets.exo5(dim=3), random_tree(9, 3, 23)]
IDS = [m.name for m in TREES]
#: The products kernels (models/derivatives.py's option ``products``) held to the full Jacobians.
PRODUCT_KERNELS = ("auto", "numba", "numpy")


def _directions(mech, samples, seed):
    rng = np.random.default_rng(seed)
    return tuple(rng.normal(size=(samples, mech.dof)) for _ in range(4))


def _mv(A, v):
    return np.einsum("sij,sj->si", A, v)


def _vm(w, A):
    return np.einsum("si,sij->sj", w, A)


@pytest.mark.parametrize("products", PRODUCT_KERNELS)
@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_inverse_dynamics_jvp_and_vjp_equal_the_full_jacobians(mech, products):
    """``dtau = dtau/dq dq + dtau/dqd dqd + M dqdd`` and ``(w^T dtau/dq, w^T dtau/dqd, w^T M)`` equal the
    products with the full Jacobians to the error model, for each products kernel (``"auto"``: the one
    ``model.derivatives`` runs, SIMD; the per-sample kernel; the numpy reference); checked to mean something
    (below 1e-12 of the largest entry). 37 samples: one whole SIMD block and a partial one."""
    q, qd, qdd = states(mech, 37, 31)
    dq, dqd, dqdd, w = _directions(mech, 37, 32)
    D = prepare(mech, "newton-euler").derivatives if products == "auto" else Derivatives(mech, products=products)
    assert D.products_kernel == {"auto": "simd"}.get(products, products)
    jq, jqd, M = D.inverse_dynamics(q, qd, qdd)
    sq, sqd = derivative_scales(mech, q, qd, qdd)
    sm = mass_matrix_scale(mech, q)
    jvp = D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd)
    ref = _mv(jq, dq) + _mv(jqd, dqd) + _mv(M, dqdd)
    scale = _mv(sq, np.abs(dq)) + _mv(sqd, np.abs(dqd)) + _mv(sm, np.abs(dqdd))
    assert_close(jvp, ref, scale, what="jvp")
    assert (K * EPS * scale <= 1e-12 * np.abs(ref).max()).all()
    for name, got, J, s in zip(
        ("w dtau/dq", "w dtau/dqd", "w M"), D.inverse_dynamics_vjp(q, qd, qdd, w), (jq, jqd, M), (sq, sqd, sm)
    ):
        assert_close(got, _vm(w, J), _vm(np.abs(w), s), what=name)


@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_forward_dynamics_jvp_and_vjp_equal_the_full_jacobians(mech):
    """The forward products equal ``J v`` and ``w^T J`` of the full forward Jacobians to ``2 K eps cond(M)
    |J| |v|`` per sample, and return the same ``qdd``."""
    q, qd, qdd = states(mech, 4, 41)
    dq, dqd, dtau, w = _directions(mech, 4, 42)
    model = prepare(mech, "newton-euler")
    D = model.derivatives
    tau = model.inverse_dynamics(q, qd, qdd)
    a, jq, jqd, Minv = D.forward_dynamics(q, qd, tau)
    cond = np.linalg.cond(model.mass_matrix(q))
    big = np.concatenate([jq, jqd, Minv], axis=2)
    norm = np.linalg.norm(big, 2, axis=(1, 2))
    a1, jvp = D.forward_dynamics_jvp(q, qd, tau, dq, dqd, dtau)
    np.testing.assert_array_equal(a1, a)
    v = np.concatenate([dq, dqd, dtau], axis=1)
    bound = 2 * K * EPS * cond * norm * np.linalg.norm(v, axis=1)
    assert (np.linalg.norm(jvp - _mv(big, v), axis=1) <= bound).all()
    a2, *vjp = D.forward_dynamics_vjp(q, qd, tau, w)
    np.testing.assert_array_equal(a2, a)
    err = np.linalg.norm(np.concatenate(vjp, axis=1) - _vm(w, big), axis=1)
    assert (err <= 2 * K * EPS * cond * norm * np.linalg.norm(w, axis=1)).all()


def test_products_take_one_sample_and_refuse_bad_shapes():
    """A ``(dof,)`` sample gives ``(dof,)`` products equal to row 0 of the batch; a direction of the wrong
    length or count, or not finite, is a ValueError naming its field."""
    mech = presets.exo5(dim=2)
    q, qd, qdd = states(mech, 3, 5)
    dq, dqd, dqdd, w = _directions(mech, 3, 6)
    D = prepare(mech, "matrix-factored").derivatives
    one = D.inverse_dynamics_jvp(q[0], qd[0], qdd[0], dq[0], dqd[0], dqdd[0])
    assert one.shape == (mech.dof,)
    np.testing.assert_allclose(one, D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd)[0], rtol=1e-14, atol=0)
    assert [x.shape for x in D.inverse_dynamics_vjp(q[0], qd[0], qdd[0], w[0])] == [(mech.dof,)] * 3
    with pytest.raises(ValueError, match=r"field 'dqd': expected shape \(samples, 10\), got \(3, 4\)"):
        D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd[:, :4], dqdd)
    with pytest.raises(ValueError, match=r"field 'w': expected 3 samples \(as q\), got 2"):
        D.inverse_dynamics_vjp(q, qd, qdd, w[:2])
    bad = dqdd.copy()
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"field 'dqdd': sample 1, entry 2: expected a finite value"):
        D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, bad)
    with pytest.raises(ValueError, match=r"field 'dtau'"):
        D.forward_dynamics_jvp(q, qd, qdd, dq, dqd, bad)
