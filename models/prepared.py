"""The prepared model: a method's per-mechanism work done once, then cheap calls.

Like Pinocchio's ``Model``/``Data`` split, :class:`PreparedModel` holds what is fixed for a
mechanism (aggregates, coupling signs, index arrays, lambdified functions, the Pinocchio model);
its calls take states and return forces, with no lookup, no cache and no validation left in the
hot path when ``check=False``.

Every method implements :meth:`PreparedModel._inverse_dynamics` on validated ``(samples, dof)``
float arrays. :meth:`PreparedModel.mass_matrix` and :meth:`PreparedModel.bias_forces` are native
where a method overrides ``_mass_matrix``/``_bias_forces`` (``native_terms`` says which) and are
otherwise derived from inverse dynamics, which is linear in ``qdd``: ``h = ID(q, qd, 0)`` and
``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)`` (:func:`terms_from_inverse_dynamics`).

**Validation.** The mechanism is validated when it is built (:class:`~models.mechanism.Mechanism`
is frozen and checks itself). ``check=True`` (the default) validates the states with
:func:`~models.mechanism.as_states`: shapes, finiteness, non-negative lengths, each with a
message that names the array, the sample and the coordinate. ``check=False`` is the fast path
for trusted hot loops (an ODE right-hand side, a controller): the arrays must already be float64
``(dof,)`` or ``(samples, dof)`` and nothing is checked.

**Threads and processes.** A prepared model holds no mutable state shared between calls other
than per-thread scratch space, so one model can serve several threads. It pickles by
reconstruction: the pickle holds the mechanism, the method's name and its options, and
unpickling prepares the model again in the receiving process (for ``lagrange`` that derives the
equations again, within the same budget).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from exo_bench.models.mechanism import Mechanism, as_states


def terms_from_inverse_dynamics(inverse_dynamics, dof: int, q: np.ndarray, qd: np.ndarray):
    """``M (S, dof, dof)`` and ``h (S, dof)`` from any inverse dynamics ``(q, qd, qdd) -> tau`` on
    ``(samples, dof)`` arrays, in ONE batched call.

    Inverse dynamics is linear in ``qdd``: ``ID(q, qd, qdd) = M(q) qdd + h(q, qd)``. Per sample the
    batch holds ``(q, qd, 0)`` (gives ``h``), ``(q, 0, 0)`` (gravity only) and ``(q, 0, e_k)`` for
    every coordinate ``k``; then ``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)``. The subtraction costs at
    most ``eps * |gravity forces| / |M e_k|`` relative, which the tests bound against CRBA.
    """
    S, d = q.shape
    k = dof + 2
    Q = np.repeat(q, k, axis=0)                      # (S*k, d): each sample's q, k times
    QD = np.zeros_like(Q)
    QD[::k] = qd                                     # first row of each block: the real rates
    QDD = np.zeros_like(Q)
    rows = np.arange(S)[:, None] * k + 2 + np.arange(d)[None, :]
    QDD[rows.ravel(), np.tile(np.arange(d), S)] = 1.0
    tau = inverse_dynamics(Q, QD, QDD).reshape(S, k, d)
    h = tau[:, 0]
    M = np.swapaxes(tau[:, 2:] - tau[:, 1:2], 1, 2)  # column k of M is ID(q, 0, e_k) - ID(q, 0, 0)
    return M, h


def _rebuild(cls, mechanism: Mechanism, options: dict):
    return cls(mechanism, **options)


class PreparedModel:
    """A mechanism prepared for one method. Subclasses set :attr:`method` and implement
    :meth:`_inverse_dynamics`; they may override ``_mass_matrix`` and ``_bias_forces``."""

    #: The registry name of the method; the algorithm timed under it.
    method: ClassVar[str] = ""

    def __init__(self, mechanism: Mechanism, **options: Any):
        if not isinstance(mechanism, Mechanism):
            raise ValueError(f"{self.method}: expected a Mechanism (exo_bench.Mechanism or exo_bench.load_mechanism), "
                             f"got {type(mechanism).__name__}")
        self._mechanism = mechanism
        self._options = dict(options)
        self._dof = mechanism.dof

    # ------------------------------------------------------------------ what it is
    @property
    def mechanism(self) -> Mechanism:
        return self._mechanism

    @property
    def options(self) -> dict:
        """The constructor options this model was prepared with (a copy)."""
        return dict(self._options)

    @property
    def dof(self) -> int:
        return self._dof

    @property
    def native_terms(self) -> bool:
        """True when :meth:`mass_matrix` and :meth:`bias_forces` are the method's own, False when
        they are derived from its inverse dynamics."""
        return type(self)._mass_matrix is not PreparedModel._mass_matrix

    def __repr__(self) -> str:
        opts = "".join(f", {k}={v!r}" for k, v in self._options.items())
        return f"<{type(self).__name__} {self.method!r} of {self._mechanism.name!r} ({self._dof} dof){opts}>"

    def __reduce__(self):
        return (_rebuild, (type(self), self._mechanism, self._options))

    # ------------------------------------------------------------------ calls
    def inverse_dynamics(self, q, qd, qdd, check: bool = True) -> np.ndarray:
        """Generalised forces ``tau = [M_phi..., M_psi..., F...]`` of the paper's absolute
        coordinates for states in block order ``[phi..., psi..., l...]``: ``(dof,)`` in gives
        ``(dof,)`` out, ``(samples, dof)`` gives ``(samples, dof)``."""
        if check:
            single = np.ndim(q) == 1
            q, qd, qdd = as_states(self._mechanism, q, qd, qdd)
            tau = self._inverse_dynamics(q, qd, qdd)
            return tau[0] if single else tau
        if q.ndim == 1:
            return self._inverse_dynamics(q[None], qd[None], qdd[None])[0]
        return self._inverse_dynamics(q, qd, qdd)

    def mass_matrix(self, q, check: bool = True) -> np.ndarray:
        """The mass matrix ``M(q) = d tau / d qdd``, ``(dof, dof)`` or ``(samples, dof, dof)``."""
        single = np.ndim(q) == 1
        if check:
            q, _, _ = as_states(self._mechanism, q)
        elif single:
            q = q[None]
        M = self._mass_matrix(q)
        return M[0] if single else M

    def bias_forces(self, q, qd, check: bool = True) -> np.ndarray:
        """``h(q, qd) = tau(q, qd, 0)``: Coriolis, centrifugal and gravity forces."""
        single = np.ndim(q) == 1
        if check:
            q, qd, _ = as_states(self._mechanism, q, qd)
        elif single:
            q, qd = q[None], qd[None]
        h = self._bias_forces(q, qd)
        return h[0] if single else h

    def mass_matrix_and_bias(self, q, qd, check: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Both terms of ``M qdd + h = tau`` at once, ``(S, dof, dof)`` and ``(S, dof)`` (batch only):
        one batched inverse-dynamics call where the terms are derived."""
        if check:
            q, qd, _ = as_states(self._mechanism, q, qd)
        if self.native_terms:
            return self._mass_matrix(q), self._bias_forces(q, qd)
        return terms_from_inverse_dynamics(self._inverse_dynamics, self._dof, q, qd)

    # ------------------------------------------------------------------ per method
    def _inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _mass_matrix(self, q: np.ndarray) -> np.ndarray:
        return terms_from_inverse_dynamics(self._inverse_dynamics, self._dof, q, np.zeros_like(q))[0]

    def _bias_forces(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self._inverse_dynamics(q, qd, np.zeros_like(q))
