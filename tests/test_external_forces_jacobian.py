"""``simulate(..., jacobian="analytic", f_ext=...)``: the implicit integrators' analytic Jacobian with
external forces (issue 37's refusal lifted where ``f_ext`` has a derivative).

The right-hand side integrates ``M qdd + h = tau(t, q, qd) + Q(q, f(t, q, qd))``, ``Q = sum_k J_k^T f_k``. Its
Jacobian needs ``dQ/dy = dQ/dq|_f + J^T df/dy``: the first from the geometry
(models/runtime/external_forces.py ``dQ_dq``), the second from the user's ``f_ext.jacobian(t, q, qd) -> (df/dq,
df/dqd)``, each ``(samples, links, 3, dim, dof)``. An ``f_ext`` without it is refused by name, as before.

Oracle: ``dQ/dy`` by complex step of ``Q(q, f(q, qd))`` (``h = 1e-30``: exact to rounding), then the
implicit-function theorem with numpy's dense solve, ``dqdd/dy = M^-1 (dtau/dy + dQ/dy - dID/dy)`` (the oracle
of tests/test_integrator_derivatives.py). **Error model**: both sides are float64 evaluations of ``X = M^-1
B`` from ``B`` equal to rounding, so they differ by about ``K eps cond(M)`` of ``max |X|`` (cond(M) below 1e3
on these states: under 2e-12); the bound 1e-9 is far below what a missing term gives (the f-through term
moves ``X`` by more than 1e-2 of it here, checked).
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.runtime import external_forces as ef
from exo_bench.models.simulation import forward_dynamics as efc
from exo_bench.models.simulation.forward_dynamics import RodSpringDamper
from exo_bench.models.mechanism.presets import random_tree
from exo_bench.models.simulation.forward_dynamics import make_jacobian, simulate

MECH = random_tree(3, 3, 5)
H = 1e-30


class LinearForces:
    """``f(t, q, qd) = F0 + A q + B qd`` at every point mass (seeded, a few newtons), with its Jacobian."""

    def __init__(self, mech, seed: int = 3):
        rng = np.random.default_rng(seed)
        self.shape = (mech.nlinks, 3, mech.dim)
        size = int(np.prod(self.shape))
        self.F0 = rng.normal(size=size)
        self.A, self.B = (rng.normal(scale=2.0, size=(size, mech.dof)) for _ in range(2))

    def __call__(self, t, q, qd):
        return (self.F0 + q @ self.A.T + qd @ self.B.T).reshape((q.shape[0], *self.shape))

    def jacobian(self, t, q, qd):
        S = q.shape[0]
        return tuple(
            np.broadcast_to(X.reshape(*self.shape, -1), (S, *self.shape, X.shape[1])) for X in (self.A, self.B)
        )


def _controls(mech):
    n = mech.nlinks
    return RodSpringDamper(n, np.full(n, 300.0), np.full(n, 5.0), np.full(n, 0.6))


def _state():
    n = MECH.nlinks
    q = np.r_[np.linspace(0.2, 1.0, n), np.linspace(-0.3, 0.4, n), np.full(n, 0.6)]
    return q, np.r_[np.full(2 * n, 0.5), np.linspace(-0.2, 0.2, n)]


def _oracle(model, controls, forces, q, qd, through: bool = True):
    """``dqdd/d(q, qd)`` by complex step of ``Q`` and a dense solve (module docstring)."""
    mech, d = model.mechanism, model.dof
    q2, qd2 = q[None], qd[None]
    f = forces(0.0, q2, qd2)
    tau = controls(0.0, q2, qd2) + ef.generalized_forces(mech, q2, f)
    qdd = model.forward_dynamics(q2, qd2, tau)
    dq, dqd, M = (a[0] for a in model.derivatives.inverse_dynamics(q2, qd2, qdd))
    cq, cqd = (a[0] for a in controls.jacobian(0.0, q2, qd2))
    Qy = np.zeros((d, 2 * d))
    for j in range(2 * d):
        y = np.concatenate([q, qd]).astype(complex)
        y[j] += 1j * H
        fy = forces(0.0, y[None, :d], y[None, d:]) if through else f
        Qy[:, j] = ef.generalized_forces(mech, y[None, :d], fy)[0].imag / H
    return np.linalg.solve(M, np.concatenate([cq, cqd], axis=1) + Qy - np.concatenate([dq, dqd], axis=1))


@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
def test_the_analytic_jacobian_with_f_ext_is_the_chain_rule(method):
    """``make_jacobian`` of the controls with external forces equals the complex-step oracle to 1e-9 of
    its largest entry; without the term through ``f`` the oracle moves by more than 1e-2 of it."""
    model = prepare(MECH, method)
    forces, controls = LinearForces(MECH), _controls(MECH)
    wrapped = efc.with_external_forces(model, controls, forces, "analytic")
    q, qd = _state()
    d = model.dof
    J = make_jacobian(model, wrapped)(0.0, np.concatenate([q, qd]))
    X = _oracle(model, controls, forces, q, qd)
    np.testing.assert_array_equal(J[:d], np.hstack([np.zeros((d, d)), np.eye(d)]))
    assert np.abs(J[d:] - X).max() <= 1e-9 * np.abs(X).max()
    assert np.abs(_oracle(model, controls, forces, q, qd, through=False) - X).max() > 1e-2 * np.abs(X).max()


def test_radau_with_the_analytic_jacobian_and_f_ext_follows_the_finite_difference_one():
    """Radau with the analytic Jacobian integrates the same motion as with scipy's finite differences
    (both at rtol 1e-8 over 0.02 s: end states within 1e-6), with fewer right-hand-side evaluations (finite differences
    spend ``2 dof`` of them per Jacobian)."""
    model = prepare(MECH, "newton-euler")
    forces, controls = LinearForces(MECH), _controls(MECH)
    q0, qd0 = _state()
    runs = {
        how: simulate(model, q0, qd0, (0.0, 0.02), controls, "Radau", rtol=1e-8, jacobian=how, f_ext=forces)
        for how in ("analytic", "finite-difference")
    }
    a, b = runs["analytic"], runs["finite-difference"]
    assert a.status == b.status == "ok" and a.jacobian == "analytic"
    np.testing.assert_allclose(a.y[-1], b.y[-1], atol=1e-6, rtol=0)
    assert a.nfev < b.nfev and a.jacobian_columns == 0 < b.jacobian_columns


def test_an_f_ext_without_a_jacobian_is_still_refused_for_the_analytic_jacobian():
    """A plain function has no derivative to use: the analytic Jacobian is refused naming the field and
    the attribute it lacks."""
    model = prepare(MECH, "newton-euler")
    q0, qd0 = _state()
    with pytest.raises(
        ValueError, match=r"field 'jacobian': expected 'finite-difference' with f_ext.*jacobian\(t, q, qd\)"
    ):
        simulate(
            model, q0, qd0, (0.0, 0.1), _controls(MECH), "Radau", jacobian="analytic", f_ext=lambda t, q, qd: 0 * q
        )
