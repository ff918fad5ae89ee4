"""The 50-digit reference of the derivatives (exo_bench.lagrange.derivative_reference): its forces are
Lagrange's 50-digit ones, CasADi's derivatives agree with it to the error model on seeded random trees
(2D and 3D, branch signs), a 1e-12 change of one element breaks that agreement, and its digits are
stable between 50 and 70. The derivatives report (bench/perf/reports/derivatives.py) is tested in
tests/test_derivatives_report.py with fake rows and a fake clock.

**Error model** (stated in the module): a float64 derivative agrees with the reference to
``K eps scale`` with ``scale`` the sum of ``|terms|`` of each entry (:func:`derivative_scale`) and
``K`` = 8 of tests/conftest.py. Forward derivatives go through ``M^-1``: their error relative to the
largest entry is bounded by ``K eps cond(M) dof`` (a backward-stable solve), ``cond`` from the
reference's own ``M`` and ``M^-1``.
"""

import mpmath
import numpy as np
import pytest
from conftest import EPS, K

from exo_bench.lagrange import derivative_reference as dr
from exo_bench.lagrange import high_precision as lr
from exo_bench.matrix_method.derivatives import Derivatives
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, random_tree

TREES = [(3, 2, 70), (5, 2, 71), (3, 3, 72), (5, 3, 73)]


@pytest.fixture(scope="module")
def casadi_of():
    pytest.importorskip("casadi")
    cache: dict = {}
    return lambda m: cache.setdefault(m, Derivatives(m))


@pytest.mark.parametrize("n,dim,seed", [(4, 2, 61), (4, 3, 63)])
def test_reference_forces_are_lagranges_50_digit_forces(n, dim, seed):
    """d'Alembert on the point masses (this reference) and Lagrange II (sympy) are two derivations:
    at 50 digits their forces agree to 1e-45 relative. (The trees of tests/test_lagrange_reference.py,
    whose symbolic derivation, seconds each, a whole run then does once.)"""
    m = random_tree(n, dim, seed)
    assert -1 in m.sign, "the trees must carry branch signs"
    q, qd, qdd = random_states(m, 3, seed)
    tau = dr.inverse_derivatives_mpf(m, q, qd, qdd)[0]
    ref = lr.inverse_dynamics_mpf(m, q, qd, qdd)
    scale = max(abs(x) for x in ref.ravel())
    assert max(abs(a - b) for a, b in zip(tau.ravel(), ref.ravel())) < mpmath.mpf(10) ** -45 * scale


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_casadi_derivatives_agree_with_the_reference_to_the_error_model(n, dim, seed, casadi_of):
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 4, seed)
    ours = casadi_of(m).inverse_dynamics(q, qd, qdd)
    ref = dr.inverse_derivatives(m, q, qd, qdd)
    scale = dr.derivative_scale(m, q, qd, qdd)
    for name, a, b, s in zip(("dtau_dq", "dtau_dqd", "M"), ours, ref, scale):
        ratio = dr.error_ratio(a, b, s)
        assert ratio <= K, f"{m.name} {name}: {ratio:.2f} eps * scale > {K}"
        assert dr.max_relative_error(a, b) < 1e-14


def test_casadi_derivatives_agree_along_exo5_3d(casadi_of):
    m = exo5(3)
    q, qd, qdd = random_states(m, 2, 5)
    ours = casadi_of(m).inverse_dynamics(q, qd, qdd)
    ref, scale = dr.inverse_derivatives(m, q, qd, qdd), dr.derivative_scale(m, q, qd, qdd)
    assert max(dr.error_ratio(a, b, s) for a, b, s in zip(ours, ref, scale)) <= K


@pytest.mark.parametrize("n,dim,seed", [(4, 2, 61), (4, 3, 75)])
def test_forward_derivatives_agree_with_casadis_implicit_function_route(n, dim, seed, casadi_of):
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 2, seed)
    tau = np.vectorize(float)(dr.inverse_derivatives_mpf(m, q, qd, qdd)[0])
    ref = dr.forward_derivatives(m, q, qd, tau)
    ours = casadi_of(m).forward_dynamics(q, qd, tau)
    Minv = ref[3]
    M = dr.inverse_derivatives(m, q, qd, ref[0])[2]
    cond = max(np.linalg.norm(a, np.inf) * np.linalg.norm(b, np.inf) for a, b in zip(M, Minv))
    bound = K * EPS * cond * m.dof
    np.testing.assert_allclose(np.einsum("sij,sjk->sik", M, Minv), np.broadcast_to(np.eye(m.dof), M.shape), atol=1e-13)
    for name, a, b in zip(("qdd", "dqdd_dq", "dqdd_dqd", "Minv"), ours, ref):
        err = dr.max_relative_error(np.atleast_3d(a), np.atleast_3d(b))
        assert err <= bound, f"{m.name} {name}: {err:.2e} > {bound:.2e}"


def test_a_1e_12_change_of_one_element_is_caught(casadi_of):
    """The agreement can fail: a mass changed by 1e-12 relative (one element of the reference's
    input) moves the derivatives by more than the error model allows."""
    m = random_tree(4, 3, 76)
    q, qd, qdd = random_states(m, 2, 76)
    masses = [list(x) for x in m.masses]
    masses[2][1] *= 1 + 1e-12
    bent = m.replace(masses=tuple(tuple(x) for x in masses))
    ours = casadi_of(m).inverse_dynamics(q, qd, qdd)
    ref, scale = dr.inverse_derivatives(bent, q, qd, qdd), dr.derivative_scale(m, q, qd, qdd)
    assert max(dr.error_ratio(a, b, s) for a, b, s in zip(ours, ref, scale)) > K


def test_a_1e_12_change_of_the_rods_accelerations_is_caught(casadi_of, monkeypatch):
    """The reference's own formulas, bent: every rod's ``w''`` scaled by ``1 + 1e-12`` is seen in
    dtau/dqd (the dual numbers differentiate what is computed, so a wrong term would be too)."""
    m = random_tree(3, 3, 77)
    q, qd, qdd = random_states(m, 2, 77)
    good = dr._link_terms

    def bent(*args):
        wdd, partials = good(*args)
        return [w * (1 + 1e-12) for w in wdd], partials

    ours = casadi_of(m).inverse_dynamics(q, qd, qdd)
    scale = dr.derivative_scale(m, q, qd, qdd)
    monkeypatch.setattr(dr, "_link_terms", bent)
    ref = dr.inverse_derivatives(m, q, qd, qdd)
    assert dr.error_ratio(ours[1], ref[1], scale[1]) > K


def test_reference_digits_agree_between_50_and_70():
    m = random_tree(3, 3, 78)
    q, qd, qdd = random_states(m, 1, 78)
    a = dr.inverse_derivatives_mpf(m, q, qd, qdd, dps=50)
    b = dr.inverse_derivatives_mpf(m, q, qd, qdd, dps=70)
    for x, y in zip(a[1:], b[1:]):
        top = max(abs(v) for v in y.ravel())
        assert max(abs(u - v) for u, v in zip(x.ravel(), y.ravel())) < mpmath.mpf(10) ** -46 * top


def test_scale_bounds_the_entries_and_is_zero_only_where_they_are():
    """The scale is a sum of |terms|: never below the entry, zero only for structural zeros (a
    branched tree's blocks off the root paths)."""
    m = random_tree(5, 3, 79)
    q, qd, qdd = random_states(m, 2, 79)
    for a, s in zip(dr.inverse_derivatives(m, q, qd, qdd), dr.derivative_scale(m, q, qd, qdd)):
        assert np.all(np.abs(a) <= s * (1 + 1e-12))
        assert np.all(a[s == 0] == 0)


def test_digits_must_be_an_integer_of_at_least_15():
    m = random_tree(2, 2, 80)
    q, qd, qdd = random_states(m, 1, 80)
    with pytest.raises(ValueError, match="dps"):
        dr.inverse_derivatives(m, q, qd, qdd, dps=10)
