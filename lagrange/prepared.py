"""Lagrange II as a prepared model: derive and lambdify once, then evaluate numpy code.

:class:`LagrangeModel` (method ``lagrange``) derives the equations of a mechanism with sympy
(:func:`exo_bench.lagrange.derive`) and lambdifies them to numpy with common-subexpression elimination in
its constructor, within a time budget. The mass matrix and the bias forces are native: the
Jacobian ``d tau / d qdd`` and ``tau(q, qd, 0)`` of the same derivation, lambdified on first use
within the same budget.

Options (constructor arguments; nothing is read from the environment):

* ``budget`` (seconds, default 120, finite): for the symbolic work. Over budget the constructor
  raises :class:`exo_bench.lagrange.BudgetExceeded` (a ValueError), whose ``skip_reason`` names the work, the
  model size and the budget. ``exo_bench.prepare`` refuses up front a derivation estimated over
  the budget (exo_bench/api/cost_model.py).
* ``interrupt`` (True or False, default True): in the main thread, a SIGALRM timer interrupts a long sympy
  call when the budget runs out (the previous handler is restored afterwards). False uses only
  the cooperative checks between steps. In other threads only those checks run.
"""

from __future__ import annotations

import contextlib


from exo_bench.lagrange import numeric
from exo_bench.lagrange.budget import without_interrupts
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.runtime.prepared import PreparedModel


class LagrangeModel(PreparedModel):
    """Method ``lagrange``: Lagrange II derived with sympy from the point masses' T and Pi,
    lambdified to numpy with CSE."""

    method = "lagrange"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        n, d = nlinks, dim
        return 8.0 * (40 * d * n * n)

    def __init__(self, mechanism: Mechanism, budget: float = numeric.DEFAULT_BUDGET, interrupt: bool = True):
        if isinstance(budget, bool) or not isinstance(budget, (int, float)) or not 0 < budget < float("inf"):
            raise ValueError(
                f"lagrange: option 'budget': expected a positive, finite number of seconds (for no "
                f"practical limit, a large one such as 1e6), got {budget!r}"
            )
        if not isinstance(interrupt, bool):  # 'x' or 0.5 would be taken as True
            raise ValueError(f"lagrange: option 'interrupt': expected True or False, got {interrupt!r}")
        super().__init__(mechanism, budget=float(budget), interrupt=bool(interrupt))
        self.budget, self.interrupt = float(budget), bool(interrupt)
        with self._signals():
            self._equations = numeric.compile_equations(mechanism, self.budget).fn
        self._mass = self._bias = None

    def _signals(self):
        return contextlib.nullcontext() if self.interrupt else without_interrupts()

    def _inverse_dynamics(self, q, qd, qdd):
        return numeric._columns(self._equations, [*q.T, *qd.T, *qdd.T], q.shape[0], self._dof)

    def _mass_matrix(self, q):
        if self._mass is None:
            with self._signals():
                self._mass = numeric.lambdify_within_budget(
                    self._mechanism, "mass matrix", self.budget, numeric._mass_matrix_build
                ).fn
        d = self._dof
        return numeric._columns(self._mass, list(q.T), q.shape[0], d * d).reshape(-1, d, d)

    def _bias_forces(self, q, qd):
        if self._bias is None:
            with self._signals():
                self._bias = numeric.lambdify_within_budget(
                    self._mechanism, "bias forces", self.budget, numeric._bias_build
                ).fn
        return numeric._columns(self._bias, [*q.T, *qd.T], q.shape[0], self._dof)
