"""Derivatives of the equations of motion for a prepared model of any method, batch-first.

``model.derivatives`` (:attr:`exo_bench.models.prepared.PreparedModel.derivatives`, attached by
``exo_bench.prepare``) is a :class:`Derivatives`:

* :meth:`Derivatives.inverse_dynamics` ``(q, qd, qdd) -> (dtau_dq, dtau_dqd, M)``: CasADi's
  algorithmic differentiation of the factored closed forms (:mod:`exo_bench.matrix_method.export.casadi_functions`);
* :meth:`Derivatives.forward_dynamics` ``(q, qd, tau) -> (qdd, dqdd_dq, dqdd_dqd, Minv)``: the
  implicit-function theorem on ``ID(q, qd, qdd) = tau``, as Pinocchio's ABA derivatives do:
  ``dqdd/dq = -M^-1 dID/dq``, ``dqdd/dqd = -M^-1 dID/dqd``, ``dqdd/dtau = M^-1``, with the
  inverse-dynamics Jacobians at the accelerations ``qdd = M^-1 (tau - h)`` and an LU solve of
  ``M`` equilibrated by ``diag(M)`` (:func:`exo_bench.models.forward_dynamics.solve_mass_matrix`).

Arrays are ``(samples, dof)`` in and ``(samples, dof, dof)`` Jacobians out (``(dof,)`` and
``(dof, dof)`` for one sample); ``J[s, i, j] = d out_i / d in_j``.

**Which physics.** The equations of motion of a mechanism are unique: every method computes the
same ``tau(q, qd, qdd)`` (the suite checks that they agree to rounding). The derivatives are those of
the matrix method's factored closed forms (what ``matrix-factored`` evaluates) for every method;
:attr:`Derivatives.source` says so per method. For ``matrix-paper`` they are the derivatives of the
correct equations, not of its printed misprints.
"""

from __future__ import annotations

import math

import numpy as np

from exo_bench.matrix_method.export.casadi_functions import casadi_functions
from exo_bench.models import forward_dynamics as fd
from exo_bench.models.conditioning import (
    CouplingCondition,
    check_conditioning,
    check_finite,
    coupling_condition,
    coupling_reason,
)
from exo_bench.models.mechanism import Mechanism, as_states
from exo_bench.models.states import is_one_sample

#: What computes the derivatives, per method family (:attr:`Derivatives.source`).
SOURCE = (
    "CasADi algorithmic differentiation of the matrix method's factored closed forms of eq. (5)/(17) "
    "(matrix_method/export/casadi_functions.py)"
)


def source_text(method: str, evaluates_these: bool, known_wrong: bool) -> str:
    """What computes the derivatives for ``method``: its own equations (``evaluates_these``, the matrix
    family), the correct ones for a method known to be wrong, or the unique equations of motion that
    every other method agrees with (the facts come from the method's MethodSpec, exo_bench.api)."""
    if known_wrong:
        return (
            f"{SOURCE}: the CORRECT equations, not {method}'s eq. (18) as printed (its 3D misprints "
            "have no derivative worth having)"
        )
    if evaluates_these:
        return f"{SOURCE}: the same equations that {method} evaluates"
    return (
        f"{SOURCE}: the equations of motion are unique, so these are {method}'s equations' derivatives to "
        "rounding (the suite checks that every method's inverse dynamics agree)"
    )


def solve_mass_matrix_columns(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``M^-1 B`` for batches ``M (S, d, d)``, ``B (S, d, k)``, equilibrated by ``D = diag(M)`` as
    :func:`exo_bench.models.forward_dynamics.solve_mass_matrix` does for one right-hand side."""
    r = 1.0 / np.sqrt(np.diagonal(M, axis1=1, axis2=2))
    Ms = M * r[:, :, None] * r[:, None, :]
    return r[:, :, None] * np.linalg.solve(Ms, r[:, :, None] * B)


class Derivatives:
    """The derivatives of one mechanism's equations of motion, for a prepared model of ``method``.
    Built by :func:`derivatives_of` (CasADi functions compiled once per mechanism)."""

    def __init__(self, mechanism: Mechanism, method: str = "matrix-factored", source: str | None = None):
        self.mechanism = mechanism
        self.method = method
        #: which physics computes these derivatives (module docstring)
        self.source = source if source is not None else source_text(method, True, False)
        self.equations = casadi_functions(mechanism)  # a ValueError naming the extra without CasADi

    def __repr__(self) -> str:
        return f"<Derivatives of {self.mechanism.name!r} for {self.method!r}: {SOURCE}>"

    def _states(self, source: str, names: tuple[str, str, str], arrays, check: bool):
        """The three arrays as ``(S, dof)`` float arrays, and whether one ``(dof,)`` sample was given.
        Shapes and sample counts are checked with or without ``check`` (a ValueError naming the field,
        the expected and the actual count: never numpy's reshape error or CasADi's); ``check`` also
        validates the values (:func:`exo_bench.models.mechanism.as_states`)."""
        single = is_one_sample(arrays[0])
        d = self.mechanism.dof
        shaped = []
        for name, a in zip(names, arrays):
            a = np.asarray(a, dtype=float) if not check else a
            nd = np.ndim(a)
            if nd not in (1, 2) or np.shape(a)[-1] != d or (nd == 1) != single:
                want = f"({d},)" if single else f"(samples, {d})"
                raise ValueError(f"{source}: field '{name}': expected shape {want}, got {np.shape(a)}")
            shaped.append(a)
        counts = [np.shape(a)[0] if not single else 1 for a in shaped]
        for name, c in zip(names[1:], counts[1:]):
            if c != counts[0]:
                raise ValueError(
                    f"{source}: field '{name}': expected {counts[0]} sample{'s' * (counts[0] != 1)} "
                    f"(as {names[0]}), got {c}"
                )
        if check:
            try:
                shaped = list(as_states(self.mechanism, shaped[0], shaped[1], shaped[2], source=source))
            except ValueError as e:  # the third array of as_states is called qdd
                raise ValueError(str(e).replace("field 'qdd'", f"field '{names[2]}'")) from None
        return [np.atleast_2d(np.asarray(a, dtype=float)) for a in shaped], single

    def inverse_dynamics(self, q, qd, qdd, check: bool = True):
        """``(dtau_dq, dtau_dqd, M)`` at the states: ``(S, dof, dof)`` each (``(dof, dof)`` for one
        ``(dof,)`` sample). ``M = dtau/dqdd``. Zero samples give ``(0, dof, dof)``."""
        (q, qd, qdd), single = self._states("inverse-dynamics derivatives", ("q", "qd", "qdd"), (q, qd, qdd), check)
        if q.shape[0] == 0:
            return tuple(np.zeros((0, self.mechanism.dof, self.mechanism.dof)) for _ in range(3))
        out = self.equations.evaluate("inverse_dynamics_derivatives", q, qd, qdd)
        return tuple(x[0] for x in out) if single else out

    @property
    def coupling_condition(self) -> CouplingCondition:
        """The mechanism's part of the condition of ``M`` (:mod:`exo_bench.models.conditioning`), on first use."""
        c = getattr(self, "_coupling_condition", None)
        if c is None:
            c = self._coupling_condition = coupling_condition(self.mechanism)
        return c

    def forward_dynamics(self, q, qd, tau, check: bool = True):
        """``(qdd, dqdd_dq, dqdd_dqd, Minv)`` at the states and forces: ``qdd (S, dof)``, the rest
        ``(S, dof, dof)`` (no sample axis for one ``(dof,)`` sample). ``Minv = dqdd/dtau``.

        With ``check`` (the default) the states are validated and they answer or refuse exactly as
        ``forward_dynamics`` does: a singular mass matrix raises
        :class:`exo_bench.models.forward_dynamics.SingularConfigurationError` naming the link, one beyond
        the conditioning bound :class:`exo_bench.models.conditioning.NumericallySingularError` (the test
        every method shares), and an answer that is not finite is refused, never returned. Without
        ``check`` only the shapes are checked, and the mechanism itself: a link that moves no mass
        (``mu`` singular at every configuration) is refused either way."""
        (q, qd, tau), single = self._states("forward-dynamics derivatives", ("q", "qd", "tau"), (q, qd, tau), check)
        mech, d = self.mechanism, self.mechanism.dof
        if math.isinf(self.coupling_condition.kappa):
            raise fd.SingularConfigurationError([f"sample 0: {coupling_reason(mech, self.coupling_condition)}"])
        if check:
            reasons = [f"sample {s}: {r}" for s, rs in enumerate(fd.singular_reasons(mech, q)) for r in rs]
            if reasons:
                raise fd.SingularConfigurationError(reasons)
            check_conditioning(mech, q, self.coupling_condition)
        if q.shape[0] == 0:
            return (np.zeros((0, d)), *(np.zeros((0, d, d)) for _ in range(3)))
        ev = self.equations.evaluate
        (M,), (h,) = ev("mass_matrix", q), ev("bias_forces", q, qd)
        qdd = fd.solve_mass_matrix(M, tau - h)
        jq, jqd, _ = ev("inverse_dynamics_derivatives", q, qd, qdd)
        X = solve_mass_matrix_columns(M, np.concatenate([jq, jqd, np.broadcast_to(np.eye(d), M.shape)], axis=2))
        out = (qdd, -X[:, :, :d], -X[:, :, d : 2 * d], X[:, :, 2 * d :])
        if check:  # never NaN or inf: the row of each Jacobian names its coordinate
            check_finite(mech, qdd)
            for x, name in zip(out[1:], ("dqdd_dq", "dqdd_dqd", "Minv")):
                check_finite(mech, np.where(np.isfinite(x).all(axis=2), 0.0, np.inf), name)
        return tuple(x[0] for x in out) if single else out


def derivatives_of(mechanism: Mechanism, method: str, source: str | None = None) -> Derivatives:
    """The provider that ``exo_bench.prepare`` attaches to a prepared model (registered in
    :data:`exo_bench.models.prepared.derivative_provider` by :mod:`exo_bench.api.preparation`)."""
    return Derivatives(mechanism, method, source)
