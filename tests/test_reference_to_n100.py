"""The analytic derivatives against the 50-digit reference up to n = 100 (issue 36's done-when item), and
the reference's two number backends.

The reference (exo_bench.lagrange.derivative_reference: d'Alembert on the point masses, exact forward-mode
dual numbers) computes at 50 digits with MPFR through gmpy2 (the [test] extra) or, without it, mpmath: a
dual evaluation of a 100-link tree costs about 1 s with gmpy2 (mpmath's ``mpf`` took 11 s for a 3D chain of
100 links). **Error model** (the module's): a float64 derivative agrees with the reference to ``K eps
scale``, ``scale`` the sum of ``|terms|`` of each entry (:func:`derivative_scale`), ``K`` of
tests/conftest.py; the reference's own error is ``1e-46 scale`` at most.
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest
from conftest import K

from exo_bench import prepare
from exo_bench.lagrange import derivative_reference as dr
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import random_tree


@pytest.mark.parametrize("dim, seed", [(2, 102), (3, 103)])
def test_analytic_derivatives_agree_with_the_50_digit_reference_at_n_100(dim, seed):
    """A seeded random tree of 100 links with branch signs, one sample: ``model.derivatives``'s
    ``dtau/dq``, ``dtau/dqd`` and ``M`` (the compiled kernels) are within ``K eps scale`` of the
    reference, entry by entry, and within 1e-13 of its largest entry."""
    mech = random_tree(100, dim, seed)
    assert -1 in mech.sign and len(set(mech.parent)) > 2, "a tree with branch signs"
    q, qd, qdd = random_states(mech, 1, seed)
    ours = prepare(mech, "newton-euler").derivatives.inverse_dynamics(q, qd, qdd)
    ref, scale = dr.inverse_derivatives(mech, q, qd, qdd), dr.derivative_scale(mech, q, qd, qdd)
    for name, a, b, s in zip(("dtau_dq", "dtau_dqd", "M"), ours, ref, scale):
        ratio = dr.error_ratio(a, b, s)
        assert ratio <= K, f"{mech.name} {name}: {ratio:.2f} eps * scale > {K}"
        assert dr.max_relative_error(a, b) < 1e-13, name


def test_the_two_backends_agree_to_their_digits():
    """MPFR (gmpy2) and mpmath round each operation to the same number of bits, not always alike: their
    derivatives agree to 1e-46 of the largest entry, as 50 and 70 digits do (tests/test_derivatives_reference.py)."""
    pytest.importorskip("gmpy2")
    m = random_tree(4, 3, 81)
    q, qd, qdd = random_states(m, 1, 81)
    a = dr.inverse_derivatives_mpf(m, q, qd, qdd, backend=dr._backend(prefer_gmpy2=True))
    b = dr.inverse_derivatives_mpf(m, q, qd, qdd, backend=dr._backend(prefer_gmpy2=False))
    assert dr._backend().name == "gmpy2"
    for x, y in zip(a, b):
        top = max(abs(v) for v in y.ravel())
        assert max(abs(u - v) for u, v in zip(x.ravel(), y.ravel())) < mpmath.mpf(10) ** -46 * top


def test_the_forward_reference_agrees_between_backends():
    """The forward derivatives' 50-digit solve (Gauss-Jordan on the backend's numbers) gives the same
    float64 answers with either backend, to 1e-15 of the largest entry (both round 50-digit numbers)."""
    pytest.importorskip("gmpy2")
    m = random_tree(4, 2, 82)
    q, qd, qdd = random_states(m, 1, 82)
    tau = prepare(m, "newton-euler").inverse_dynamics(q, qd, qdd)
    a = dr.forward_derivatives(m, q, qd, tau, backend=dr._backend(prefer_gmpy2=True))
    b = dr.forward_derivatives(m, q, qd, tau, backend=dr._backend(prefer_gmpy2=False))
    for x, y in zip(a, b):
        assert np.abs(x - y).max() <= 1e-15 * np.abs(y).max()
