"""The implicit integrators' Jacobian comes from the analytic derivatives of ``model.derivatives``
(issue 36): models/simulation/forward_dynamics.py ``make_jacobian``, models/simulation/forward_dynamics.py.

Oracle: the provider's own *inverse*-dynamics derivatives ``(dID/dq, dID/dqd, M)`` at ``qdd = FD(q, qd,
tau)``, through the implicit-function theorem with numpy's dense solve: ``dqdd/dy = M^-1 (dtau_ctrl/dy -
dID/dy)``, a route that shares neither the provider's column-by-column ``M^-1`` nor its forward-dynamics
derivatives. Error model: both are float64 evaluations of ``X = M^-1 B`` from the same exact ``B``:
``|dX| <= 2 K eps (cond(M) |X| + |M^-1| S sqrt(dof))``, ``S`` the scale of the terms of ``B`` (the terms
of tau over the shortest rod, as in tests/test_analytic_jacobian.py, plus the springs' k and c).
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

from conftest import EPS, K, term_scale
from exo_bench import prepare
from exo_bench.bench.studies.stability.forward_cases import ATOL_FACTOR, stiff_case
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.simulation.forward_dynamics import make_jacobian, simulate

METHODS = ("newton-euler", "matrix-factored", "recurrence")


@pytest.fixture(scope="module")
def case():
    return stiff_case(1e4)


def _states(case, seed: int = 7):
    rng = np.random.default_rng(seed)
    d = case.mechanism.dof
    q = case.q0 + rng.uniform(-0.2, 0.2, d) * np.r_[np.ones(d - case.mechanism.nlinks), np.zeros(case.mechanism.nlinks)]
    q[-case.mechanism.nlinks :] *= rng.uniform(0.95, 1.05, case.mechanism.nlinks)
    return np.concatenate([q, rng.uniform(-1, 1, d)])


@pytest.mark.parametrize("method", METHODS)
def test_integrators_jacobian_is_the_providers_derivatives(case, method, monkeypatch):
    """``make_jacobian`` against the implicit-function theorem on the provider's inverse-dynamics
    derivatives, for several methods; CasADi is unimportable during the call (the derivatives are the
    analytic kernels, not CasADi's)."""
    mech = case.mechanism
    d = mech.dof
    model = prepare(mech, method)
    monkeypatch.setitem(sys.modules, "casadi", None)  # any import of casadi now raises ImportError
    assert "analytic" in model.derivatives.source
    y = _states(case)
    J = make_jacobian(model, case.controls)(0.0, y)
    q, qd = y[None, :d], y[None, d:]
    tau = case.controls(0.0, q, qd)
    qdd = model.forward_dynamics(q, qd, tau)
    dq, dqd, M = (a[0] for a in model.derivatives.inverse_dynamics(q, qd, qdd))
    cq, cqd = (a[0] for a in case.controls.jacobian(0.0, q, qd))
    X = np.linalg.solve(M, np.concatenate([cq - dq, cqd - dqd], axis=1))
    np.testing.assert_array_equal(J[:d], np.hstack([np.zeros((d, d)), np.eye(d)]))
    n = mech.nlinks
    S = term_scale(mech, q, qd, qdd).max() * 2 / min(q[0, -n:].min(), 1.0) + case.k + np.max(case.c)
    cond, minv = np.linalg.cond(M), np.linalg.norm(np.linalg.inv(M), 2)
    Xn = np.linalg.norm(X, 2)
    bound = 2 * K * EPS * (cond * Xn + minv * S * math.sqrt(d))
    assert np.linalg.norm(J[d:] - X, 2) <= bound
    assert bound <= 1e-6 * Xn, "the bound would not test anything"


def test_radau_and_bdf_take_the_providers_jacobians_and_fewer_evaluations(case):
    """Every Jacobian an analytic run takes is one call of the provider's forward-dynamics derivatives
    (counted), and those runs take fewer right-hand-side evaluations than scipy's finite differences
    at the same rtol (tests/test_analytic_jacobian.py checks the tolerance reached)."""
    model = prepare(case.mechanism, "newton-euler")
    derivatives = model.derivatives
    calls = {"n": 0}
    forward = derivatives.forward_dynamics

    def counted(*args, **kwargs):
        calls["n"] += 1
        return forward(*args, **kwargs)

    derivatives.forward_dynamics = counted
    try:
        for integ in fd.IMPLICIT:
            calls["n"] = 0
            run = lambda j: simulate(
                model, case.q0, case.qd0, (0.0, 0.2), case.controls, integ, 1e-4, ATOL_FACTOR * 1e-4, jacobian=j
            )
            f, a = run("finite-difference"), run("analytic")
            assert f.ok and a.ok
            assert calls["n"] == a.njev > 1
            assert a.jacobian_columns == 0 and a.nfev < f.nfev, (integ, a.nfev, f.nfev)
    finally:
        del derivatives.forward_dynamics
