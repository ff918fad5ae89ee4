"""CasADi's derivatives of the equations of motion: for symbolic use, export and as a cross-check.

``model.derivatives`` is the analytic provider (:mod:`exo_bench.models.derivatives`: the Newton-Euler
passes differentiated, forward dynamics without dense LU) for every method. This module keeps
CasADi's algorithmic differentiation of the matrix method's factored closed forms of eq. (5)/(17)
(:mod:`exo_bench.matrix_method.export.casadi_functions`) behind the same calls and checks: reach it with
``derivatives_of(mechanism, method)`` (the optional extra ``casadi``; a ValueError naming the extra
without it):

* :meth:`Derivatives.inverse_dynamics` ``(q, qd, qdd) -> (dtau_dq, dtau_dqd, M)``: CasADi's AD;
* :meth:`Derivatives.forward_dynamics` ``(q, qd, tau) -> (qdd, dqdd_dq, dqdd_dqd, Minv)``: the
  implicit-function theorem on ``ID(q, qd, qdd) = tau``, as Pinocchio's ABA derivatives do, with an LU
  solve of ``M`` equilibrated by ``diag(M)`` (:func:`exo_bench.models.simulation.forward_dynamics.solve_mass_matrix`).
  The directional derivatives (JVP, VJP) run through these too.

Arrays, refusals and one-sample calls are those of :class:`exo_bench.models.derivatives.Derivatives`.
For ``matrix-paper`` they are the derivatives of the correct equations, not of its printed misprints.
"""

from __future__ import annotations

import numpy as np

from exo_bench.matrix_method.export.casadi_functions import casadi_functions
from exo_bench.models import derivatives as analytic
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.mechanism.mechanism import Mechanism

#: What computes CasADi's derivatives (:attr:`Derivatives.source`).
SOURCE = (
    "CasADi algorithmic differentiation of the matrix method's factored closed forms of eq. (5)/(17) "
    "(matrix_method/export/casadi_functions.py)"
)


def source_text(method: str, evaluates_these: bool, known_wrong: bool) -> str:
    """What computes CasADi's derivatives for ``method`` (:func:`exo_bench.models.derivatives.source_text`)."""
    return analytic.source_text(method, evaluates_these, known_wrong, SOURCE)


def solve_mass_matrix_columns(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``M^-1 B`` for batches ``M (S, d, d)``, ``B (S, d, k)``, equilibrated by ``D = diag(M)`` as
    :func:`exo_bench.models.simulation.forward_dynamics.solve_mass_matrix` does for one right-hand side."""
    r = 1.0 / np.sqrt(np.diagonal(M, axis1=1, axis2=2))
    Ms = M * r[:, :, None] * r[:, None, :]
    return r[:, :, None] * np.linalg.solve(Ms, r[:, :, None] * B)


class Derivatives(analytic.Derivatives):
    """CasADi's derivatives of one mechanism's equations of motion (CasADi functions compiled once per
    mechanism), with the checks of :class:`exo_bench.models.derivatives.Derivatives`."""

    def __init__(self, mechanism: Mechanism, method: str = "matrix-factored", source: str | None = None):
        self.equations = casadi_functions(mechanism)  # a ValueError naming the extra without CasADi
        super().__init__(mechanism, method, source if source is not None else source_text(method, True, False), "numpy")

    def _inverse(self, q, qd, qdd):
        return tuple(self.equations.evaluate("inverse_dynamics_derivatives", q, qd, qdd))

    def _accelerations(self, q, qd, tau):
        ev = self.equations.evaluate
        (M,), (h,) = ev("mass_matrix", q), ev("bias_forces", q, qd)
        return fd.solve_mass_matrix(M, tau - h)

    def _forward_jacobians(self, q, qd, qdd, tau):
        """``-M^-1 dID/dq``, ``-M^-1 dID/dqd`` and ``M^-1`` by one equilibrated LU solve of CasADi's ``M``."""
        jq, jqd, M = self._inverse(q, qd, qdd)
        d = M.shape[-1]
        X = solve_mass_matrix_columns(M, np.concatenate([jq, jqd, np.broadcast_to(np.eye(d), M.shape)], axis=2))
        return -X[:, :, :d], -X[:, :, d : 2 * d], X[:, :, 2 * d :]

    def _solve(self, q, B, out=None):
        (M,) = self.equations.evaluate("mass_matrix", q)
        X = solve_mass_matrix_columns(M, B)
        if out is None:
            return X
        out[...] = X
        return out


def derivatives_of(mechanism: Mechanism, method: str, source: str | None = None) -> Derivatives:
    """CasADi's derivatives for a prepared model of ``method`` (``model.derivatives`` is the analytic
    provider, :func:`exo_bench.models.derivatives.derivatives_of`)."""
    return Derivatives(mechanism, method, source)
