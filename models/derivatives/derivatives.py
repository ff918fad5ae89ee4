"""Derivatives of the equations of motion for a prepared model of any method, batch-first, analytic.

``model.derivatives`` (:attr:`exo_bench.models.runtime.prepared.PreparedModel.derivatives`, registered by
``exo_bench.api.preparation``) is a :class:`Derivatives`:

* :meth:`Derivatives.inverse_dynamics` ``(q, qd, qdd) -> (dtau_dq, dtau_dqd, M)``: the analytic derivatives
  of the Newton-Euler passes (:mod:`exo_bench.models.newton_euler.derivatives`), O(1) work per
  entry of the output;
* :meth:`Derivatives.forward_dynamics` ``(q, qd, tau) -> (qdd, dqdd_dq, dqdd_dqd, Minv)``: the
  implicit-function theorem on ``ID(q, qd, qdd) = tau`` at ``qdd = FD(q, qd, tau)``: ``dqdd/dq = -M^-1
  dID/dq``, ``dqdd/dqd = -M^-1 dID/dqd``, ``dqdd/dtau = M^-1``, with ``M^-1`` as ``dof`` columns of the
  O(n) forward dynamics (:mod:`exo_bench.models.newton_euler.inverse_mass`, ``M^-1 = J^-1 (mu^-1 (x) I)
  J^-T``) and ``M^-1 dID`` from it and the per-rod columns
  (:mod:`exo_bench.models.newton_euler.forward_jacobians`): O(n^2) time and memory, the size of the
  output, and no dense LU;
* the directional derivatives, O(n) per sample, for users who need no full Jacobian
  (:mod:`exo_bench.models.newton_euler.products`, compiled across SIMD lanes in
  :mod:`exo_bench.models.newton_euler.products_simd` and per sample in
  :mod:`exo_bench.models.newton_euler.products_compiled`; the option ``products`` and
  :attr:`Derivatives.products_kernel` say which runs): :meth:`Derivatives.inverse_dynamics_jvp` ``(q,
  qd, qdd, dq, dqd, dqdd) -> dtau``, :meth:`Derivatives.inverse_dynamics_vjp` ``(q, qd, qdd, w) -> (w^T dtau/dq,
  w^T dtau/dqd, w^T M)``, and the same of forward dynamics (:meth:`Derivatives.forward_dynamics_jvp`,
  :meth:`Derivatives.forward_dynamics_vjp`). With ``check=False`` and float64 C-contiguous arrays of one
  shape the inverse products go from the call to the kernel with no conversion (:meth:`Derivatives._lean_products`):
  exo5-3d's JVP and VJP cost about 2x a batched inverse dynamics per sample.

Arrays are ``(samples, dof)`` in and ``(samples, dof, dof)`` Jacobians out (``(dof,)`` and ``(dof, dof)``
for one sample); ``J[s, i, j] = d out_i / d in_j``. The equations of motion are unique (the suite checks
that every method's inverse dynamics agree to rounding), so one provider serves every method and
:attr:`Derivatives.source` says so. **CasADi's** algorithmic differentiation of the matrix method's
factored closed forms stays for symbolic use, export and as a cross-check:
``exo_bench.matrix_method.derivatives.derivatives_of(mechanism, method)`` (the same calls, the extra
``casadi``). The memory of a call is estimated before the work (:func:`derivative_bytes`) and a call over
what a run may use is refused (:class:`DerivativesTooLarge`) before anything is allocated.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exo_bench.models.machine import memory
from exo_bench.models.derivatives.derivatives_products import DirectionalDerivatives, _products_option, _samples
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.runtime.result_pool import ResultPool


#: What computes the derivatives (:attr:`Derivatives.source`).
SOURCE = (
    "analytic O(n) derivatives of the Newton-Euler passes (models/newton_euler/derivatives.py); "
    "forward dynamics by the implicit-function theorem, M^-1 applied column by column by the O(n) "
    "forward dynamics (models/newton_euler/inverse_mass.py), no dense LU"
)
#: Bytes per sample beyond the Jacobians: the states, ``qdd`` and the per-rod columns (``(n, dim, dim)``
#: each, four of them, under 8 dof), in float64 entries per coordinate.
PER_COORDINATE = 64


class DerivativesTooLarge(memory.CallTooLarge):
    """A derivative call whose estimated memory exceeds what a run may use, refused before any work."""


def derivative_bytes(dof: int, samples: int, jacobians: int = 3, kernel: str = "numba") -> float:
    """Estimated peak bytes of one derivative call: ``jacobians`` ``(samples, dof, dof)`` float64 arrays
    (the output), the inverse-dynamics Jacobians a forward call solves in place, O(n) per sample
    (:data:`PER_COORDINATE`), and with the numpy kernel the columns as samples (``(samples, dof, dof)``
    twice more: :func:`exo_bench.models.newton_euler.inverse_mass.numpy_columns`)."""
    square = float(samples) * dof * dof * 8.0
    extra = 3 * square if REFERENCE[kernel] and jacobians else 0.0  # the products solve no columns
    return jacobians * square + extra + float(samples) * dof * PER_COORDINATE * 8.0


def source_text(method: str, own: bool, known_wrong: bool, source: str = SOURCE) -> str:
    """What computes the derivatives for ``method``: its own equations (``own``), the correct ones for a
    method known to be wrong, or the unique equations of motion that every other method agrees with (the
    facts come from the method's MethodSpec, exo_bench.api)."""
    if known_wrong:
        return (
            f"{source}: the CORRECT equations, not {method}'s eq. (18) as printed (its 3D misprints "
            "have no derivative worth having)"
        )
    if own:
        return f"{source}: the same equations that {method} evaluates"
    return (
        f"{source}: the equations of motion are unique, so these are {method}'s equations' derivatives to "
        "rounding (the suite checks that every method's inverse dynamics agree)"
    )


#: The option ``kernel``: whether it runs the numpy reference (else the compiled kernels); ``"auto"`` is
#: numba unless ``NUMBA_DISABLE_JIT``.
REFERENCE = {"numba": False, "numpy": True}


def _kernel(option: str) -> str:
    if option != "auto" and option not in REFERENCE:
        raise ValueError(f"derivatives: option 'kernel': expected 'auto', 'numba' or 'numpy', got {option!r}")
    if option != "auto":
        return option
    from exo_bench.models.machine.numba_runtime import jit_disabled

    return {True: "numpy", False: "numba"}[jit_disabled()]


class Derivatives(DirectionalDerivatives):
    """The derivatives of one mechanism's equations of motion, for a prepared model of ``method``.

    ``kernel``: ``"numba"`` (compiled), ``"numpy"`` (the reference) or ``"auto"`` (numba unless
    ``NUMBA_DISABLE_JIT``); ``products``: the kernel of the directional derivatives
    (:data:`exo_bench.models.derivatives.derivatives_products.PRODUCT_KERNELS`). Subclasses (CasADi's, :mod:`exo_bench.matrix_method.derivatives`) replace
    :meth:`_inverse`, :meth:`_accelerations`, :meth:`_solve` and :meth:`_forward_jacobians` and keep every
    check (:class:`exo_bench.models.derivatives.derivative_checks.DerivativeChecks`: states, singular states, no NaN out)."""

    def __init__(
        self,
        mechanism: Mechanism,
        method: str = "newton-euler",
        source: str | None = None,
        kernel="auto",
        products: str = "auto",
    ):
        from exo_bench.models.newton_euler.derivatives import RECYCLE_MIN_BYTES, prepare_inverse_derivatives

        self.mechanism = mechanism
        self.method = method
        self.kernel = _kernel(kernel)
        self._products_option = _products_option(products)
        self._products_scratch = None  # the SIMD products kernel's ThreadScratch (products_scratch)
        #: runs the numpy reference (the option ``kernel``, :data:`REFERENCE`), else the compiled kernels
        self.reference = REFERENCE[self.kernel]
        #: which physics computes these derivatives (module docstring)
        self.source = source if source is not None else SOURCE
        #: the analytic inverse-dynamics derivatives (:mod:`exo_bench.models.newton_euler.derivatives`), whose
        #: tree and table the forward passes share
        self.inverse_derivatives = prepare_inverse_derivatives(mechanism)
        self.tree, self.table = self.inverse_derivatives.tree, self.inverse_derivatives.table
        #: new batched results of the forward calls, recycled once dropped (models/runtime/result_pool.py): the
        #: four of two calls (a loop holds the previous ones during the next call), from the size the
        #: inverse derivatives recycle (:data:`exo_bench.models.newton_euler.derivatives.RECYCLE_MIN_BYTES`)
        self._results = ResultPool(keep=8, min_bytes=RECYCLE_MIN_BYTES)

    def __repr__(self) -> str:
        return f"<Derivatives of {self.mechanism.name!r} for {self.method!r}: {self.source}>"

    # ------------------------------------------------------------------ the numbers (replaced by subclasses)
    def _inverse(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(dtau_dq, dtau_dqd, M)`` on validated ``(S, dof)`` arrays with ``S >= 1``."""
        q, qd, qdd = (np.ascontiguousarray(a) for a in (q, qd, qdd))  # the kernels take C-ordered states
        return self.inverse_derivatives(q, qd, qdd, kernel={True: "numpy", False: "auto"}[self.reference])

    def _accelerations(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``qdd = FD(q, qd, tau)`` by the O(n) passes."""
        dim, g = self.mechanism.dim, float(self.mechanism.g)
        if self.reference:
            from exo_bench.models.newton_euler import passes

            return passes.forward_dynamics(self.tree, dim, g, q, qd, tau)
        from exo_bench.models.newton_euler import compiled
        from exo_bench.models.machine.numba_runtime import run

        x, xd, y = (np.ascontiguousarray(a).reshape(-1) for a in (q, qd, tau))
        o = self._results.empty(q.shape)
        args = (self.table, g, dim, True, x, xd, y, o.reshape(-1))
        run(compiled.newton_euler, compiled.newton_euler_parallel, args, q.shape[0])
        return o

    def _solve(self, q: np.ndarray, B: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``M(q)^-1 B`` for ``B (S, dof, k)``, into ``out`` (which may be ``B``) or a new array."""
        from exo_bench.models.newton_euler import inverse_mass

        if self.reference:
            X = inverse_mass.numpy_columns(self.tree, self.mechanism.dim, q, B)
            if out is None:
                return X
            out[...] = X
            return out
        from exo_bench.models.machine.numba_runtime import run

        o = np.empty(B.shape) if out is None else out
        args = (self.table, self.mechanism.dim, np.ascontiguousarray(q), np.ascontiguousarray(B), o)
        run(inverse_mass.columns, inverse_mass.columns_parallel, args, q.shape[0])
        return o

    def _forward_jacobians(
        self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """``(dqdd_dq, dqdd_dqd, Minv)`` at ``qdd = FD(q, qd, tau)``: ``M^-1`` by ``dof`` columns of the O(n)
        forward dynamics, the rest from it and the per-rod columns
        (:mod:`exo_bench.models.newton_euler.forward_jacobians`, compiled in
        :mod:`exo_bench.models.newton_euler.forward_jacobians_compiled`)."""
        S, d = q.shape
        Minv = self._results.empty((S, d, d))
        Minv[...] = np.eye(d)  # the columns of M^-1 I, solved in place
        Minv = self._solve(q, Minv, out=Minv)
        if self.reference:
            from exo_bench.models.newton_euler.forward_jacobians import forward_jacobians

            jq, jqd = forward_jacobians(self.tree, self.mechanism.dim, float(self.mechanism.g), q, qd, qdd, Minv)
            return jq, jqd, Minv
        from exo_bench.models.newton_euler import forward_jacobians_compiled as fc
        from exo_bench.models.machine.numba_runtime import run

        jq, jqd = self._results.empty((S, d, d)), self._results.empty((S, d, d))
        states = (np.ascontiguousarray(a) for a in (q, qd, qdd, tau))
        run(fc.forward_jacobians, fc.forward_jacobians_parallel, (self.mechanism.dim, *states, Minv, jq, jqd), S)
        return jq, jqd, Minv

    # ------------------------------------------------------------------ checks
    def _check_memory(self, source: str, samples: int, jacobians: int) -> None:
        """Refuse, before any work, a call whose :func:`derivative_bytes` exceed :func:`exo_bench.models.machine.memory.usable_memory`
        (asked only above :data:`exo_bench.models.machine.memory.CHUNK_BYTES`)."""
        need = derivative_bytes(self.mechanism.dof, samples, jacobians, self.kernel)
        what = f"{jacobians} Jacobians of (samples, dof, dof) float64 and their work" if jacobians else "O(n) work"
        memory.check_call(source, samples, self.mechanism.dof, need, what, DerivativesTooLarge)

    # ------------------------------------------------------------------ full Jacobians
    def inverse_dynamics(self, q, qd, qdd, check: bool = True):
        """``(dtau_dq, dtau_dqd, M)`` at the states: ``(S, dof, dof)`` each (``(dof, dof)`` for one
        ``(dof,)`` sample). ``M = dtau/dqdd``. Zero samples give ``(0, dof, dof)``. With ``check`` (the
        default) a state where forward dynamics is refused (``M`` singular or beyond the conditioning
        bound) is refused, naming the sample and the link (:meth:`_refuse_singular_states`); without it
        the values are finite there too (inverse dynamics is a polynomial in ``l``, ``cos`` and ``sin``)."""
        source = "inverse-dynamics derivatives"
        samples = _samples(q)
        self._check_memory(source, samples, 3)  # before the states are copied
        (q, qd, qdd), single = self._states(source, ("q", "qd", "qdd"), (q, qd, qdd), check)
        d = self.mechanism.dof
        if samples != q.shape[0]:  # a list: estimated once converted
            self._check_memory(source, q.shape[0], 3)
        if check:
            self._refuse_singular_states(q, source)
        if q.shape[0] == 0:
            return tuple(np.zeros((0, d, d)) for _ in range(3))
        out = self._inverse(q, qd, qdd)
        return tuple(x[0] for x in out) if single else tuple(out)

    def forward_dynamics(self, q, qd, tau, check: bool = True):
        """``(qdd, dqdd_dq, dqdd_dqd, Minv)`` at the states and forces: ``qdd (S, dof)``, the rest
        ``(S, dof, dof)`` (no sample axis for one ``(dof,)`` sample). ``Minv = dqdd/dtau``.

        With ``check`` (the default) the states are validated and they answer or refuse exactly as
        ``forward_dynamics`` does: a singular mass matrix raises
        :class:`exo_bench.models.simulation.forward_dynamics.SingularConfigurationError` naming the link, one beyond
        the conditioning bound :class:`exo_bench.models.runtime.conditioning.NumericallySingularError` (the test
        every method shares), and an answer that is not finite is refused, never returned. Without
        ``check`` only the shapes are checked, and the mechanism itself: a link that moves no mass
        (``mu`` singular at every configuration) is refused either way."""
        source = "forward-dynamics derivatives"
        samples = _samples(q)
        self._check_memory(source, samples, 3)  # before the states are copied
        (q, qd, tau), single = self._states(source, ("q", "qd", "tau"), (q, qd, tau), check)
        d = self.mechanism.dof
        if samples != q.shape[0]:  # a list: estimated once converted
            self._check_memory(source, q.shape[0], 3)
        self._refuse_singular(q, check)
        if q.shape[0] == 0:
            return (np.zeros((0, d)), *(np.zeros((0, d, d)) for _ in range(3)))
        qdd = self._accelerations(q, qd, tau)
        out = (qdd, *self._forward_jacobians(q, qd, qdd, tau))
        if check:
            self._finite(out, ("qdd", "dqdd_dq", "dqdd_dqd", "Minv"))
        return tuple(x[0] for x in out) if single else out


def derivatives_of(mechanism: Mechanism, method: str, source: str | None = None, **options: Any) -> Derivatives:
    """The provider that ``exo_bench.prepare`` attaches to a prepared model of any method (registered in
    :data:`exo_bench.models.runtime.prepared.derivative_provider` by :mod:`exo_bench.api.preparation`)."""
    return Derivatives(mechanism, method, source, **options)
