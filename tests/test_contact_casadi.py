"""The CasADi form of the ground contact (models/simulation/contact.py) is the numpy form, and CasADi's
derivatives of it are the closed-form Jacobians (models/simulation/contact.py).

Error model: the two forms evaluate the same operations in possibly different orders (CasADi's
expression graph), a few roundings per term: 1e-13 of the largest force or Jacobian entry of the batch.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.models.simulation.contact import ContactParameters, contact_force_jacobians

ca = pytest.importorskip("casadi")

from exo_bench.models.simulation.contact import contact_function  # noqa: E402


def _cases(dim: int, n: int = 40):
    rng = np.random.default_rng(10 + dim)
    p = rng.normal(0, 0.3, (n, dim))
    p[:, -1] = rng.uniform(-0.02, 0.01, n)
    v = rng.normal(0, 0.5, (n, dim))
    v[:5, :-1] = 0.0  # no slip
    p[5:10, -1] = 0.0  # on the floor
    p[10, -1], v[10, -1] = -1e3, 1e3  # deep and pulling out fast: the unused branches overflow
    p[11, -1] = 1e3  # far above
    return p, v


@pytest.mark.parametrize("dim", [2, 3])
def test_casadi_force_and_jacobians_equal_the_numpy_ones(dim):
    c = ContactParameters(static_friction=1.0, dynamic_friction=0.7)
    fun = contact_function(dim, c)
    p_sym, v_sym = ca.SX.sym("p", dim), ca.SX.sym("v", dim)
    f_sym = fun(p_sym, v_sym)
    jac = ca.Function("contact_jacobians", [p_sym, v_sym], [ca.jacobian(f_sym, p_sym), ca.jacobian(f_sym, v_sym)])
    p, v = _cases(dim)
    f, jp, jv = contact_force_jacobians(p, v, c)
    for k in range(len(p)):
        got = np.asarray(fun(p[k], v[k])).ravel()
        gp, gv = (np.asarray(x) for x in jac(p[k], v[k]))
        assert np.all(np.isfinite(got)) and np.all(np.isfinite(gp)) and np.all(np.isfinite(gv)), k
        np.testing.assert_allclose(got, f[k], rtol=0, atol=1e-13 * np.abs(f).max())
        np.testing.assert_allclose(gp, jp[k], rtol=0, atol=1e-13 * np.abs(jp).max())
        np.testing.assert_allclose(gv, jv[k], rtol=0, atol=1e-13 * np.abs(jv).max())


def test_a_bad_dimension_is_named():
    with pytest.raises(ValueError, match="contact: field 'dim': expected 2 or 3, got 4"):
        contact_function(4)
