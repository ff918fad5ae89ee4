"""The 50-digit mpmath reference: agreement with float64 evaluation, stability of its digits, exact
input conversion (checked on the hand-derived one-link eq. 2 at 50 digits)."""

import mpmath
import numpy as np
import pytest
from conftest import assert_forces_agree

from exo_bench.lagrange import numeric as ln
from exo_bench.lagrange import high_precision as lr
from exo_bench.models.gait.motion import gait, random_states
from exo_bench.models.mechanism.presets import exo5, fig1, random_tree


@pytest.mark.parametrize("n,dim,seed", [(2, 2, 60), (4, 2, 61), (3, 3, 62), (4, 3, 63)])
def test_50_digit_reference_agrees_with_float64_on_random_states(n, dim, seed):
    """The reference is exact to float64 (rounded once), so the float64 evaluation is within the
    error model of tests/conftest.py of it, with only one side rounding."""
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 20, seed)
    assert_forces_agree(ln.inverse_dynamics(m, q, qd, qdd), lr.inverse_dynamics(m, q, qd, qdd), m, q, qd, qdd)


def test_50_digit_reference_agrees_with_float64_along_the_exo5_gait():
    m = exo5(3)
    mo = gait(m, np.linspace(0.0, 1.1, 12))
    assert_forces_agree(
        ln.inverse_dynamics(m, mo.q, mo.qd, mo.qdd), lr.inverse_dynamics(m, mo.q, mo.qd, mo.qdd), m, mo.q, mo.qd, mo.qdd
    )


def test_reference_digits_agree_between_50_and_80_digits():
    m = random_tree(3, 3, 64)
    q, qd, qdd = random_states(m, 3, 1)
    a = lr.inverse_dynamics_mpf(m, q, qd, qdd, dps=50)
    b = lr.inverse_dynamics_mpf(m, q, qd, qdd, dps=80)
    scale = max(abs(x) for x in b.ravel())
    assert all(isinstance(x, mpmath.mpf) for x in a.ravel())
    assert max(abs(x - y) for x, y in zip(a.ravel(), b.ravel())) < mpmath.mpf(10) ** -45 * scale


def test_one_link_reference_is_eq2_at_50_digits_with_exact_inputs():
    """Inputs 0.1, 0.7, ... are not decimal-exact in binary: the reference must use the binary
    values exactly, as eq. (2) evaluated here at 60 digits from mpf(float) does."""
    m = fig1(2)
    q, qd, qdd = np.array([[0.1, 0.7]]), np.array([[0.3, -0.2]]), np.array([[1.1, 0.9]])
    tau = lr.inverse_dynamics_mpf(m, q, qd, qdd, dps=50)[0]
    with mpmath.workdps(60):
        f = mpmath.mpf
        (m0, m1, m2), n, g = [f(x) for x in m.masses[0]], f(m.n[0]), f(m.g)
        zeta, eta = m1 * n**2 + m2, m1 * n + m2
        phi, l, w, ld, wdd, ldd = (f(x) for x in (0.1, 0.7, 0.3, -0.2, 1.1, 0.9))
        M = l**2 * zeta * wdd + g * l * eta * mpmath.cos(phi) + 2 * l * zeta * ld * w
        F = -l * zeta * w**2 + g * eta * mpmath.sin(phi) + zeta * ldd
        assert abs(tau[0] - M) < f(10) ** -47 * abs(M)
        assert abs(tau[1] - F) < f(10) ** -47 * abs(F)
        # the decimal 0.1 would give a different answer in the 17th digit
        M_decimal = M - g * l * eta * (mpmath.cos(phi) - mpmath.cos(mpmath.mpf("0.1")))
        assert abs(tau[0] - M_decimal) > f(10) ** -20 * abs(M)


def test_digits_must_be_an_integer_of_at_least_15():
    m = fig1(2)
    q, qd, qdd = random_states(m, 1, 0)
    with pytest.raises(ValueError, match="dps"):
        lr.inverse_dynamics(m, q, qd, qdd, dps=10)
