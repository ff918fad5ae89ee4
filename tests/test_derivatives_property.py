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
from conftest import EPS, K, assert_close, mass_matrix_scale
from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_derivatives_analytic import H, complex_step, derivative_scales
from test_properties import mechanisms, states

from exo_bench.models.mechanism.mechanism import Mechanism
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


def complex_step_floor(dof: int) -> float:
    """The complex step's own resolution, in units of ``eps`` (added to the scale of a comparison with it):
    it reads a derivative term ``t`` from the imaginary part ``H t``, which underflows (gradual underflow:
    absolute error at most ``2**-1074`` per operation) when ``|H t|`` is below the smallest normal number, so
    terms under about ``2**-1074 / H`` (2.5e-294 at H = 1e-30) are lost; bounded by 64 operations per
    coordinate."""
    return 64 * dof * 2.0**-1074 / H / EPS


#: Found by CI (fresh clone, 2026-11-27): qdd of 7.6e-305 at a zero-length rod; the complex step lost the
#: term qdd * dM/dq (7.6e-305 * H underflows to zero), the kernels kept it.
_TINY = Mechanism(
    dim=2,
    g=9.81,
    parent=(-1, 0, 0),
    sign=(1, 1, 1),
    masses=((1.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 0.0, 1.0)),
    n=(1e-06, 1e-06, 1e-06),
    names=("link1", "link2", "link3"),
    name="hypothesis",
)
_TINY_Q = np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 1.0]] * 2 + [[0.0, 0.0, 0.0, 1.0, 1.0, 1.0]] * 2)
_TINY_QDD = np.zeros((4, 6))
_TINY_QDD[3, 5] = 7.60228659e-305


@FEW
@given(shaped_cases())
@example((_TINY, 4, _TINY_Q, np.zeros((4, 6)), _TINY_QDD))
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
    floor = complex_step_floor(mech.dof)
    assert_close(ref[0], cq, sq + floor, K, what="numpy dtau_dq against the complex step")
    assert_close(ref[1], cqd, sqd + floor, K, what="numpy dtau_dqd against the complex step")
    for kernel in ("numba", "simd", "auto"):
        got = [np.reshape(x, (-1, mech.dof, mech.dof)) for x in results[kernel]]
        for name, a, b, sc in zip(("dtau_dq", "dtau_dqd", "M"), got, ref, scales):
            assert_close(a, b, sc, K, what=f"{kernel} {name}")
        np.testing.assert_array_equal(got[2], np.swapaxes(got[2], 1, 2), err_msg=f"{kernel}: M symmetric")
