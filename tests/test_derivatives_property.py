"""The analytic derivatives of inverse dynamics over hypothesis's mechanisms and states (those of
tests/test_properties.py: trees of 1 to 5 links, several roots, branch signs, zero masses, near-vertical
and vertical rods, zero and tiny lengths, angles to 4 pi, rates to 30; 2D and 3D) and over shapes (a
``(dof,)`` sample, batches of 0 to 35 samples: whole and partial SIMD blocks).

Properties: every kernel returns the shapes asked; ``dtau/dq`` and ``dtau/dqd`` equal complex-step
derivatives of the numpy passes and the kernels agree with each other, both within the error model of
tests/test_derivatives_analytic.py (``K eps`` times the magnitudes of the terms; its ``1/l`` makes it
vacuous at ``l = 0``, where only finiteness is asserted); ``M`` is exactly symmetric from the compiled
kernels (``M_ji`` multiplies the same factors in the same order as ``M_ij``).
"""

from __future__ import annotations

import numpy as np
from conftest import K, assert_close, mass_matrix_scale
from hypothesis import given, settings
from hypothesis import strategies as st
from test_derivatives_analytic import complex_step, derivative_scales
from test_properties import mechanisms, states

from exo_bench.models.newton_euler.derivatives import prepare_inverse_derivatives

FEW = settings(max_examples=10, deadline=None, derandomize=True, database=None)


@st.composite
def shaped_cases(draw):
    """A mechanism, a batch size (None: one ``(dof,)`` sample) and states of that shape."""
    mech = draw(mechanisms())
    q, qd, qdd = draw(states(mech))  # 4 samples each
    size = draw(st.sampled_from([None, 0, 1, 4, 35]))
    if size is None:
        return mech, None, q[0].copy(), qd[0].copy(), qdd[0].copy()
    take = np.arange(size) % q.shape[0]
    return mech, size, *(np.ascontiguousarray(x[take]) for x in (q, qd, qdd))


@FEW
@given(shaped_cases())
def test_kernels_agree_with_the_complex_step_and_each_other(case):
    mech, size, q, qd, qdd = case
    d = prepare_inverse_derivatives(mech)
    want = (mech.dof, mech.dof) if size is None else (size, mech.dof, mech.dof)
    results = {k: d(q, qd, qdd, kernel=k) for k in ("numpy", "numba", "simd", "auto")}
    for kernel, got in results.items():
        assert all(x.shape == want for x in got), kernel
        assert all(np.isfinite(x).all() for x in got), kernel
    if size == 0:
        return
    q2, qd2, qdd2 = (np.atleast_2d(x) for x in (q, qd, qdd))
    with np.errstate(divide="ignore"):
        sq, sqd = derivative_scales(mech, q2, qd2, qdd2)
    scales = (sq, sqd, mass_matrix_scale(mech, q2))
    cq, cqd = complex_step(mech, q2, qd2, qdd2)
    ref = [np.reshape(x, (-1, mech.dof, mech.dof)) for x in results["numpy"]]
    assert_close(ref[0], cq, sq, K, what="numpy dtau_dq against the complex step")
    assert_close(ref[1], cqd, sqd, K, what="numpy dtau_dqd against the complex step")
    for kernel in ("numba", "simd", "auto"):
        got = [np.reshape(x, (-1, mech.dof, mech.dof)) for x in results[kernel]]
        for name, a, b, sc in zip(("dtau_dq", "dtau_dqd", "M"), got, ref, scales):
            assert_close(a, b, sc, K, what=f"{kernel} {name}")
        np.testing.assert_array_equal(got[2], np.swapaxes(got[2], 1, 2), err_msg=f"{kernel}: M symmetric")
