"""The derivatives of every prepared model's equations of motion (``model.derivatives``): the Jacobians of
inverse and forward dynamics and their directional products, computed for every method by the analytic
Newton-Euler passes (:mod:`exo_bench.models.newton_euler`), with their checks and memory estimate. Above the
method it computes with; CasADi's derivatives of the matrix method stay in ``exo_bench.matrix_method``.

Derivatives of the equations of motion for a prepared model of any method, batch-first, analytic.

``model.derivatives`` (:attr:`exo_bench.models.runtime.prepared.PreparedModel.derivatives`) is a :class:`Derivatives`:

* :meth:`Derivatives.inverse_dynamics` ``(q, qd, qdd) -> (dtau_dq, dtau_dqd, M)``: the analytic derivatives
  of the Newton-Euler passes (:mod:`exo_bench.models.newton_euler.derivatives`), O(1) work per
  entry of the output;
* :meth:`Derivatives.forward_dynamics` ``(q, qd, tau) -> (qdd, dqdd_dq, dqdd_dqd, Minv)``: the
  implicit-function theorem on ``ID(q, qd, qdd) = tau`` at ``qdd = FD(q, qd, tau)``: ``dqdd/dq = -M^-1
  dID/dq``, ``dqdd/dqd = -M^-1 dID/dqd``, ``dqdd/dtau = M^-1``, with ``M^-1`` as ``dof`` columns of the
  O(n) forward dynamics (:mod:`exo_bench.models.newton_euler.forward_jacobians`, ``M^-1 = J^-1 (mu^-1 (x) I)
  J^-T``) and ``M^-1 dID`` from it and the per-rod columns
  (:mod:`exo_bench.models.newton_euler.forward_jacobians`): O(n^2) time and memory, the size of the
  output, and no dense LU;
* the directional derivatives, O(n) per sample, for users who need no full Jacobian
  (:mod:`exo_bench.models.newton_euler.products`, compiled across SIMD lanes in
  :mod:`exo_bench.models.newton_euler.products_simd` and per sample in
  :mod:`exo_bench.models.newton_euler.products`; the option ``products`` and
  :attr:`Derivatives.products_kernel` say which runs): :meth:`Derivatives.inverse_dynamics_jvp` ``(q,
  qd, qdd, dq, dqd, dqdd) -> dtau``, :meth:`Derivatives.inverse_dynamics_vjp` ``(q, qd, qdd, w) -> (w^T dtau/dq,
  w^T dtau/dqd, w^T M)``, and the same of forward dynamics (:meth:`Derivatives.forward_dynamics_jvp`,
  :meth:`Derivatives.forward_dynamics_vjp`).

Arrays are ``(samples, dof)`` in and ``(samples, dof, dof)`` Jacobians out (``(dof,)`` and ``(dof, dof)``
for one sample); ``J[s, i, j] = d out_i / d in_j``. The equations of motion are unique (the suite checks
that every method's inverse dynamics agree to rounding), so one provider serves every method and
:attr:`Derivatives.source` says so. **CasADi's** algorithmic differentiation of the matrix method's
factored closed forms stays for symbolic use, export and as a cross-check:
``exo_bench.matrix_method.derivatives.derivatives_of(mechanism, method)`` (the same calls, the extra
``casadi``).

**One way through each call.** Every public call validates its arrays once, at the edge
(:meth:`Derivatives._edge`), then runs its kernel. The edge refuses a call whose memory
(:func:`derivative_bytes`) exceeds what a run may use (:class:`DerivativesTooLarge`) before anything is
allocated or converted; then the arrays pass the one array gate (:mod:`exo_bench.models.states.array_gate`: a
base-class C-contiguous float64 ndarray of the exact shape reaches a kernel, nothing else; ``check=True``
converts what numpy reads as real numbers, ``check=False`` converts nothing and refuses the rest, naming
the field); with ``check`` the states' values are validated (:func:`exo_bench.models.states.states.checked_states`)
and singular states refused, naming the sample and the link. The common case (plain arrays, states clear
of every bound) is decided by compiled passes with no Python call; only what they do not clear takes the
exact checks, which decide and name why. One ``(dof,)`` sample of :meth:`Derivatives.inverse_dynamics`
is one compiled call (:func:`exo_bench.models.newton_euler.derivatives_simd.checked_one`: the checks of
``check`` and the kernel a batch runs, an int back) into three new ``(dof, dof)`` arrays.
"""

from __future__ import annotations

import functools
import threading
from typing import Any

import numpy as np

from exo_bench.models.states import array_gate
from exo_bench.models.machine import memory
from exo_bench.models.runtime.conditioning import (
    CouplingCondition,
    check_conditioning,
    check_finite,
    coupling_condition,
    coupling_reason,
)
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.runtime.prepared import ResultPool
from exo_bench.models.mechanism.singularity import SingularConfigurationError, mechanism_reasons, singular_reasons
from exo_bench.models.states.states import checked_states, coordinate_names

_ND = np.ndarray
_F8 = np.dtype(np.float64)

#: What computes the derivatives (:attr:`Derivatives.source`).
SOURCE = (
    "analytic O(n) derivatives of the Newton-Euler passes (models/newton_euler/derivatives.py); "
    "forward dynamics by the implicit-function theorem, M^-1 applied column by column by the O(n) "
    "forward dynamics (models/newton_euler/forward_jacobians.py), no dense LU"
)
#: Bytes per sample beyond the Jacobians: the states, ``qdd`` and the per-rod columns (``(n, dim, dim)``
#: each, four of them, under 8 dof), in float64 entries per coordinate.
PER_COORDINATE = 64
#: The option ``kernel``: whether it runs the numpy reference (else the compiled kernels); ``"auto"`` is
#: numba unless ``NUMBA_DISABLE_JIT``.
REFERENCE = {"numba": False, "numpy": True}
#: The option ``products``: the kernel of the directional derivatives (:attr:`Derivatives.products_kernel`),
#: each the name of the method that runs it (a table: no branch on a kernel's name): ``"simd"``
#: (:mod:`exo_bench.models.newton_euler.products_simd`, blocks of samples across SIMD lanes), ``"numba"``
#: (:mod:`exo_bench.models.newton_euler.products`, per sample), ``"numpy"`` (the reference), or
#: ``"auto"`` (:data:`AUTO`).
PRODUCT_KERNELS = {"auto": "", "simd": "_simd_products", "numba": "_compiled_products", "numpy": "_reference_products"}
#: ``products="auto"``: mechanisms of at least this many links run the per-sample products kernel. The SIMD
#: kernel's scratch, 53 rows of 32 samples per link (13.6 kB), leaves the caches as n grows: 3D chains, 64
#: samples, one process, load 2.7-3.1 (provisional), SIMD against per-sample, us per sample: n = 100 JVP 6.0
#: / 20.8, VJP 6.8 / 19.5; n = 300 25 / 65 and 39 / 67; n = 500 66 / 110 and 94 / 111; n = 800 250 / 209 and
#: 211 / 207 (per link, the SIMD JVP's 60 ns at n <= 100 grows to 83, 131 and 312 ns).
PRODUCTS_SIMD_BELOW_LINKS = 500
#: ``products="auto"`` by (the numpy reference runs, at least :data:`PRODUCTS_SIMD_BELOW_LINKS` links): the
#: reference under ``kernel="numpy"``, else the SIMD kernel, and the per-sample kernel for the largest mechanisms.
AUTO = {(True, False): "numpy", (True, True): "numpy", (False, False): "simd", (False, True): "numba"}

#: The calls: what their messages start with, the names of their arrays, how many of those are states
#: (validated as states with ``check``; the rest are directions or weights, checked finite), the number of
#: ``(S, dof, dof)`` Jacobians they return (the memory estimate), and which singular states they refuse
#: (``"inverse"``: the states where forward dynamics refuses, with ``check``; ``"forward"``: those and a
#: mechanism with a link that moves no mass, with or without ``check``).
_INVERSE = ("inverse-dynamics derivatives", ("q", "qd", "qdd"), 3, 3, "inverse")
_FORWARD = ("forward-dynamics derivatives", ("q", "qd", "tau"), 3, 3, "forward")
_INVERSE_JVP = ("inverse-dynamics JVP", ("q", "qd", "qdd", "dq", "dqd", "dqdd"), 3, 0, "inverse")
_INVERSE_VJP = ("inverse-dynamics VJP", ("q", "qd", "qdd", "w"), 3, 0, "inverse")
_FORWARD_JVP = ("forward-dynamics JVP", ("q", "qd", "tau", "dq", "dqd", "dtau"), 3, 0, "forward")
_FORWARD_VJP = ("forward-dynamics VJP", ("q", "qd", "tau", "w"), 3, 0, "forward")


class DerivativesTooLarge(memory.CallTooLarge):
    """A derivative call whose estimated memory exceeds what a run may use, refused before any work."""


def derivative_bytes(dof: int, samples: int, jacobians: int = 3, kernel: str = "numba") -> float:
    """Estimated peak bytes of one derivative call: ``jacobians`` ``(samples, dof, dof)`` float64 arrays
    (the output), the inverse-dynamics Jacobians a forward call solves in place, O(n) per sample
    (:data:`PER_COORDINATE`), and with the numpy kernel the columns as samples (``(samples, dof, dof)``
    twice more: :func:`exo_bench.models.newton_euler.forward_jacobians.numpy_columns`)."""
    square = float(samples) * dof * dof * 8.0
    extra = 3 * square if REFERENCE[kernel] and jacobians else 0.0  # the products solve no columns
    return jacobians * square + extra + float(samples) * dof * PER_COORDINATE * 8.0


def source_text(method: str, own: bool, known_wrong: bool, source: str = SOURCE) -> str:
    """What computes the derivatives for ``method``: its own equations (``own``), the correct ones for a
    method known to be wrong, or the unique equations of motion that every other method agrees with (the
    facts are the prepared-model class's: ``derivatives_are_its_own``, ``known_wrong``)."""
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


def _kernel(option: str) -> str:
    if option != "auto" and option not in REFERENCE:
        raise ValueError(f"derivatives: option 'kernel': expected 'auto', 'numba' or 'numpy', got {option!r}")
    if option != "auto":
        return option
    from exo_bench.models.machine.numba_runtime import jit_disabled

    return {True: "numpy", False: "numba"}[jit_disabled()]


def _products_option(option) -> str:
    if option not in PRODUCT_KERNELS:
        raise ValueError(f"derivatives: option 'products': expected one of {tuple(PRODUCT_KERNELS)}, got {option!r}")
    return option


def _samples(q: Any) -> int:
    """The sample count of an array ``(samples, dof)`` (1 for one sample), read from its shape without
    converting it; 0 for what has no shape (a list: estimated once converted)."""
    shape = getattr(q, "shape", None)
    return int(shape[0]) if isinstance(shape, tuple) and len(shape) == 2 else 0 if shape is None else 1


class Derivatives:
    """The derivatives of one mechanism's equations of motion, for a prepared model of ``method``.

    ``kernel``: ``"numba"`` (compiled), ``"numpy"`` (the reference) or ``"auto"`` (numba unless
    ``NUMBA_DISABLE_JIT``); ``products``: the kernel of the directional derivatives
    (:data:`PRODUCT_KERNELS`). A subclass (CasADi's, :mod:`exo_bench.matrix_method.derivatives`) replaces
    :meth:`_inverse`, :meth:`_accelerations`, :meth:`_solve` and :meth:`_forward_jacobians` and keeps the
    edge (:meth:`_edge`: the arrays, the states, singular states) and the check that no NaN goes out."""

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
        d = mechanism.dof
        self._dof, self._nlinks, self._one_shape, self._square = d, mechanism.nlinks, (d,), (d, d)
        #: bytes per sample of a call with and without full Jacobians (:func:`derivative_bytes`): the edge
        #: asks for the memory only above :data:`exo_bench.models.machine.memory.CHUNK_BYTES`
        self._bytes = {j: derivative_bytes(d, 1, j, self.kernel) for j in (0, 3)}
        #: new batched results, recycled once dropped (models/runtime/prepared.py): the four of two forward
        #: calls (a loop holds the previous ones during the next call), from the size the inverse
        #: derivatives recycle (:data:`exo_bench.models.newton_euler.derivatives.RECYCLE_MIN_BYTES`)
        self._results = ResultPool(keep=8, min_bytes=RECYCLE_MIN_BYTES)
        #: the compiled kernels run one sample of inverse dynamics in one compiled call (:meth:`inverse_dynamics`)
        self._compiled_one = not self.reference and type(self)._inverse is Derivatives._inverse
        #: the compiled kernels run forward dynamics' Jacobians in one compiled call (:meth:`_forward_all`)
        self._fused_forward = (
            not self.reference
            and type(self)._accelerations is Derivatives._accelerations
            and type(self)._forward_jacobians is Derivatives._forward_jacobians
        )
        self._one: tuple | None = None  # that call's entry point and fixed arguments (_resolve_one)
        self._local = threading.local()  # each thread's packed workspace of that call
        self._checks: tuple | None = None  # the compiled checks of a batch (_resolve_checks)
        self._simd_batch: tuple | None = None  # the batched SIMD kernel's driver (_inverse)
        self._product_calls: dict | None = None  # the products kernel's calls (_resolve_products)
        self._coupling_condition: CouplingCondition | None = None

    def __repr__(self) -> str:
        return f"<Derivatives of {self.mechanism.name!r} for {self.method!r}: {self.source}>"

    # ------------------------------------------------------------------ the numbers (replaced by subclasses)
    def _inverse(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(dtau_dq, dtau_dqd, M)`` on plain ``(S, dof)`` arrays with ``S >= 1``: the batched kernel
        into new (or recycled) results."""
        ids = self.inverse_derivatives
        out = self._results.empties((q.shape[0], self._dof, self._dof), 3)
        simd = self._simd_batch
        if simd is None:  # the SIMD kernel's driver where kernel "auto" runs it, once: () where it does not
            simd = self._simd_batch = () if self.reference else ids.auto_simd() or ()
        if self.reference:
            ids._numpy(q, qd, qdd, out)
        elif simd:
            run, kernel, params, scratch = simd
            run(kernel, params, q.reshape(-1), qd.reshape(-1), qdd.reshape(-1), tuple(out), q.shape[0], scratch=scratch)
        else:
            ids._numba(q, qd, qdd, out)
        return tuple(out)

    def _accelerations(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``qdd = FD(q, qd, tau)`` by the O(n) passes."""
        dim, g = self.mechanism.dim, float(self.mechanism.g)
        if self.reference:
            from exo_bench.models.newton_euler import passes

            return passes.forward_dynamics(self.tree, dim, g, q, qd, tau)
        from exo_bench.models.newton_euler import compiled
        from exo_bench.models.machine.numba_runtime import run

        (o,) = self._results.empties(q.shape, 1)
        args = (self.table, g, dim, True, q.reshape(-1), qd.reshape(-1), tau.reshape(-1), o.reshape(-1))
        run(compiled.newton_euler, compiled.newton_euler_parallel, args, q.shape[0])
        return o

    def _solve(self, q: np.ndarray, B: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """``M(q)^-1 B`` for ``B (S, dof, k)``, into ``out`` (which may be ``B``) or a new array."""
        from exo_bench.models.newton_euler import forward_jacobians

        if self.reference:
            X = forward_jacobians.numpy_columns(self.tree, self.mechanism.dim, q, B)
            if out is None:
                return X
            out[...] = X
            return out
        from exo_bench.models.machine.numba_runtime import run

        o = np.empty(B.shape) if out is None else out
        args = (self.table, self.mechanism.dim, q, np.ascontiguousarray(B), o)
        run(forward_jacobians.columns, forward_jacobians.columns_parallel, args, q.shape[0])
        return o

    def _forward_jacobians(
        self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, tau: np.ndarray
    ) -> tuple[np.ndarray, ...]:
        """``(dqdd_dq, dqdd_dqd, Minv)`` at ``qdd = FD(q, qd, tau)``: ``M^-1`` by ``dof`` columns of the O(n)
        forward dynamics, the rest from it and the per-rod columns
        (:mod:`exo_bench.models.newton_euler.forward_jacobians`, compiled in
        :mod:`exo_bench.models.newton_euler.forward_jacobians_compiled`)."""
        S, d = q.shape
        Minv, jq, jqd = self._results.empties((S, d, d), 3)
        Minv[...] = np.eye(d)  # the columns of M^-1 I, solved in place
        Minv = self._solve(q, Minv, out=Minv)
        if self.reference:
            from exo_bench.models.newton_euler.forward_jacobians import forward_jacobians

            jq, jqd = forward_jacobians(self.tree, self.mechanism.dim, float(self.mechanism.g), q, qd, qdd, Minv)
            return jq, jqd, Minv
        from exo_bench.models.newton_euler import forward_jacobians_compiled as fc
        from exo_bench.models.machine.numba_runtime import run

        run(
            fc.forward_jacobians, fc.forward_jacobians_parallel, (self.mechanism.dim, q, qd, qdd, tau, Minv, jq, jqd), S
        )
        return jq, jqd, Minv

    def _forward_all(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, ...]:
        """``(qdd, dqdd_dq, dqdd_dqd, Minv)`` of the compiled kernels in one compiled call
        (:func:`exo_bench.models.newton_euler.forward_jacobians_compiled.forward_derivatives`: :meth:`_accelerations`,
        :meth:`_solve` of ``I`` and :meth:`_forward_jacobians`, the same bits), into new (or recycled) results."""
        from exo_bench.models.newton_euler import forward_jacobians_compiled as fc
        from exo_bench.models.machine.numba_runtime import run

        S, d = q.shape
        (qdd,) = self._results.empties(q.shape, 1)
        Minv, jq, jqd = self._results.empties((S, d, d), 3)
        args = (self.table, float(self.mechanism.g), self.mechanism.dim, q, qd, tau, qdd, Minv, jq, jqd)
        run(fc.forward_derivatives, fc.forward_derivatives_parallel, args, S)
        return qdd, jq, jqd, Minv

    # ------------------------------------------------------------------ the directional derivatives' kernels
    @property
    def products_kernel(self) -> str:
        """The kernel that computes the directional derivatives (:data:`PRODUCT_KERNELS`): ``"simd"``,
        ``"numba"`` or ``"numpy"``, the option ``products`` resolved for this mechanism."""
        option = self._products_option
        if option != "auto":
            return option
        return AUTO[(self.reference, self.mechanism.nlinks >= PRODUCTS_SIMD_BELOW_LINKS)]

    @property
    def products_scratch(self):
        """Each thread's scratch of the SIMD products kernel (made at its first use)."""
        if self._products_scratch is None:
            from exo_bench.models.newton_euler import products_simd
            from exo_bench.models.machine.simd_blocks import ThreadScratch

            m = self.mechanism
            self._products_scratch = ThreadScratch(products_simd.scratch, m.nlinks, m.dim)
        return self._products_scratch

    def _products(self, which: str, *arrays):
        """The ``"jvp"`` or ``"vjp"`` of inverse dynamics on plain ``(S, dof)`` arrays, O(n) per sample, by
        :attr:`products_kernel` (:data:`PRODUCT_KERNELS`): its two calls, bound once (:meth:`_resolve_products`)."""
        return (self._product_calls or self._resolve_products())[which](*arrays)

    def _resolve_products(self) -> dict:
        """``{"jvp": f, "vjp": f}`` of :attr:`products_kernel`, each ``f(q, qd, qdd, ...)`` with the mechanism's
        numbers bound (:data:`PRODUCT_KERNELS` names the method that binds them)."""
        self._product_calls = {w: getattr(self, PRODUCT_KERNELS[self.products_kernel])(w) for w in ("jvp", "vjp")}
        return self._product_calls

    def _simd_products(self, which: str):
        """Across SIMD lanes (:mod:`exo_bench.models.newton_euler.products_simd`)."""
        from exo_bench.models.newton_euler import products_simd

        dim, g = int(self.mechanism.dim), float(self.mechanism.g)
        return functools.partial(getattr(products_simd, which), self.table, dim, g, scratch=self.products_scratch)

    def _compiled_products(self, which: str, reference: bool = False):
        """Per sample, compiled (:mod:`exo_bench.models.newton_euler.products`), or its numpy reference."""
        from exo_bench.models.newton_euler import products as pc

        m = self.mechanism
        return functools.partial(getattr(pc, which), self.tree, self.table, m.dim, float(m.g), reference=reference)

    def _reference_products(self, which: str):
        """The numpy reference (:mod:`exo_bench.models.newton_euler.products`)."""
        return self._compiled_products(which, reference=True)

    # ------------------------------------------------------------------ the edge: every check, once
    def _edge(self, call: tuple, arrays: tuple, check: bool) -> tuple[tuple[np.ndarray, ...], bool]:
        """The arrays of one call (``call``: :data:`_INVERSE` and the others) as plain ``(S, dof)`` arrays,
        and whether one ``(dof,)`` sample was given; every check of the call, in this order: the memory
        (:meth:`_check_memory`, before anything is converted), the arrays (:mod:`exo_bench.models.states.array_gate`),
        with ``check`` the states' values (:func:`exo_bench.models.states.states.checked_states`) and the finiteness
        of the directions, then the singular states (:meth:`_refuse_singular`). Plain arrays whose states
        clear every bound pass by two compiled calls and no Python call (:meth:`_resolve_checks`)."""
        source, names, states, jacobians, singular = call
        shape, d = getattr(arrays[0], "shape", None), self._dof
        if type(shape) is tuple and (shape == self._one_shape or (len(shape) == 2 and shape[1] == d)):
            for a in arrays:  # array_gate.is_plain, written out (no Python call)
                if type(a) is not _ND or a.shape != shape or a.dtype is not _F8:
                    break
                f = a.flags
                if not (f.c_contiguous and f.aligned):
                    break
            else:
                single = len(shape) == 1
                if single:
                    two = []
                    for a in arrays:
                        two.append(a.reshape(1, d))
                    arrays = tuple(two)
                elif shape[0] * self._bytes[jacobians] > memory.CHUNK_BYTES:
                    self._check_memory(source, shape[0], jacobians)
                q = arrays[0]
                vplan, status, fplan, clear = self._checks or self._resolve_checks()
                if not check:
                    if singular == "inverse" or not np.isinf(
                        (self._coupling_condition or self.coupling_condition).kappa
                    ):
                        return arrays, single
                elif status(q, arrays[1], arrays[2], 3, vplan) == 0 and clear(q, self._nlinks, fplan):
                    if states == len(arrays) or np.isfinite(arrays[states:]).all():
                        return arrays, single
        return self._exact_edge(call, arrays, check)

    def _exact_edge(self, call: tuple, arrays: tuple, check: bool) -> tuple[tuple[np.ndarray, ...], bool]:
        """:meth:`_edge` for what its compiled passes did not clear: every check in Python, each refusal
        naming the field (and the sample, the coordinate or the link)."""
        source, names, states, jacobians, singular = call
        d = self._dof
        samples = _samples(arrays[0])
        if samples != 1:
            self._check_memory(source, samples, jacobians)  # before the states are copied
        single = _one_sample(arrays[0])
        for name, a in zip(names, arrays):  # shapes and sample counts first, with or without check
            nd = np.ndim(a)
            if nd not in (1, 2) or np.shape(a)[-1] != d or (nd == 1) != single:
                want = f"({d},)" if single else f"(samples, {d})"
                raise ValueError(f"{source}: field '{name}': expected shape {want}, got {np.shape(a)}")
        counts = [1 if single else np.shape(a)[0] for a in arrays]
        for name, c in zip(names[1:], counts[1:]):
            if c != counts[0]:
                raise ValueError(
                    f"{source}: field '{name}': expected {counts[0]} sample{'s' * (counts[0] != 1)} "
                    f"(as {names[0]}), got {c}"
                )
        shaped: list[Any]
        if not check:
            shaped = list(array_gate.as_states(arrays, names, d, source, False))  # converts nothing: refuses, naming
        else:
            shaped = list(arrays)
            for k in range(states, len(arrays)):  # a direction or weight: through the gate (converted), then finite
                shaped[k] = array_gate.as_input(arrays[k], names[k], np.shape(arrays[k]), source, True)
            try:
                got = checked_states(self.mechanism, shaped[0], shaped[1], shaped[2], source=source)
            except ValueError as e:  # the third array of checked_states is called qdd
                raise ValueError(str(e).replace("field 'qdd'", f"field '{names[2]}'")) from None
            shaped[:3] = got
            for name, a in zip(names[states:], shaped[states:]):
                bad = ~np.isfinite(a)
                if bad.any():
                    s, j = (int(x[0]) for x in np.nonzero(np.atleast_2d(bad)))
                    raise ValueError(f"{source}: field '{name}': sample {s}, entry {j}: expected a finite value")
        two = tuple(a.reshape(1, d) if a.ndim == 1 else a for a in shaped)
        if two[0].shape[0] != samples:  # a list: estimated once converted
            self._check_memory(source, two[0].shape[0], jacobians)
        if singular == "inverse":
            if check:
                self._refuse_singular_states(two[0], source)
        else:
            self._refuse_singular(two[0], check)
        return two, single

    def _resolve_checks(self) -> tuple:
        """The compiled checks of :meth:`_edge`, resolved once per model: the states' validation pass of
        two-dimensional arrays and its plan (:mod:`exo_bench.models.states.validation_pass`), and the clearance of
        the singular states and its plan (:mod:`exo_bench.models.runtime.forward_check`)."""
        from exo_bench.models.runtime.forward_check import entries, plan_of
        from exo_bench.models.states.states import state_check, validation_plan

        mech = self.mechanism
        vplan = validation_plan(mech)
        chk = state_check(mech)
        status = (chk.by_ndim or chk.resolve())[2]
        self._checks = (vplan, status, plan_of(mech, self.coupling_condition), entries().clear_2d)
        return self._checks

    def _check_memory(self, source: str, samples: int, jacobians: int) -> None:
        """Refuse, before any work, a call whose :func:`derivative_bytes` exceed
        :func:`exo_bench.models.machine.memory.usable_memory` (asked only above :data:`exo_bench.models.machine.memory.CHUNK_BYTES`)."""
        need = derivative_bytes(self._dof, samples, jacobians, self.kernel)
        what = f"{jacobians} Jacobians of (samples, dof, dof) float64 and their work" if jacobians else "O(n) work"
        memory.check_call(source, samples, self._dof, need, what, DerivativesTooLarge)

    @property
    def coupling_condition(self) -> CouplingCondition:
        """The mechanism's part of the condition of ``M`` (:mod:`exo_bench.models.runtime.conditioning`), on first use."""
        c = self._coupling_condition
        if c is None:
            c = self._coupling_condition = coupling_condition(self.mechanism)
        return c

    def _clear(self, q: np.ndarray) -> bool:
        """Every sample of plain ``(S, dof)`` ``q`` clears the singular and conditioning bounds by a margin:
        the compiled pass of :mod:`exo_bench.models.runtime.forward_check` (False: the exact checks decide and name why)."""
        _, _, fplan, clear = self._checks or self._resolve_checks()
        return bool(clear(np.ascontiguousarray(q, dtype=np.float64), self.mechanism.nlinks, fplan))

    def _refuse_singular(self, q: np.ndarray, check: bool) -> None:
        """What forward dynamics refuses: a link that moves no mass (with or without ``check``), and with
        ``check`` a singular state (naming the link) or one beyond the conditioning bound."""
        mech = self.mechanism
        if np.isinf(self.coupling_condition.kappa):
            raise SingularConfigurationError([f"sample 0: {coupling_reason(mech, self.coupling_condition)}"])
        if check and not self._clear(q):
            reasons = [f"sample {s}: {r}" for s, rs in enumerate(singular_reasons(mech, q)) for r in rs]
            if reasons:
                raise SingularConfigurationError(reasons)
            check_conditioning(mech, q, self.coupling_condition)

    def _refuse_singular_states(self, q: np.ndarray, source: str) -> None:
        """The inverse calls' refusal (with ``check``): the states where forward dynamics refuses (a rod of
        length zero, a vertical rod, beyond the conditioning bound), with its reasons prefixed by
        ``source``. Inverse dynamics has no division, but ``M = dtau/dqdd`` is singular there and the
        chart of a vertical rod is. A link that moves no mass is the mechanism's, not the states': there
        the inverse calls stay defined (and the states' conditioning is not estimated)."""
        if self._clear(q):
            return
        mech = self.mechanism
        always = set(mechanism_reasons(mech))
        reasons = [f"sample {s}: {r}" for s, rs in enumerate(singular_reasons(mech, q)) for r in rs if r not in always]
        try:
            if reasons:
                raise SingularConfigurationError(reasons)
            if coupling_reason(mech, self.coupling_condition) is None:
                check_conditioning(mech, q, self.coupling_condition)
        except SingularConfigurationError as e:
            e.args = (f"{source}: {e}",)
            raise

    def _finite_inverse(self, source: str, out: tuple[np.ndarray, ...], names: tuple[str, ...]) -> None:
        """Never NaN or inf from an inverse product (``(S, dof)`` arrays): a ValueError naming the field of
        the result, the sample, the coordinate and its link (inverse dynamics is defined there; the
        inputs are too large for float64). One isfinite pass per array."""
        for x, name in zip(out, names):
            if np.isfinite(x).all():  # not a sum under np.errstate: entering one costs ~5 us
                continue
            s, j = (int(i) for i in np.argwhere(~np.isfinite(x))[0])
            i, mech = j % self.mechanism.nlinks, self.mechanism
            raise ValueError(
                f"{source}: field '{name}' sample {s} coordinate {coordinate_names(mech)[j]} (link {i + 1}, "
                f"{mech.names[i]!r}): expected a finite result, got {x[s, j]!r}: the directions, weights or "
                "states are too large for float64"
            )

    def _finite(self, out: tuple[np.ndarray, ...], names: tuple[str, ...]) -> None:
        """Never NaN or inf: a vector names its coordinate, a Jacobian the row of its coordinate."""
        for x, name in zip(out, names):
            if np.isfinite(x.sum()):  # one pass, no temporary: NaN and inf propagate (a false alarm only on overflow)
                continue
            if x.ndim == 2:
                check_finite(self.mechanism, x, name)
            else:
                check_finite(self.mechanism, np.where(np.isfinite(x).all(axis=2), 0.0, np.inf), name)

    # ------------------------------------------------------------------ one sample, compiled
    def _resolve_one(self) -> tuple:
        """The compiled per-sample entry of :meth:`inverse_dynamics`
        (:func:`exo_bench.models.newton_euler.derivatives_simd.checked_one`, its entry point for plain arrays
        resolved once: :func:`exo_bench.models.runtime.prepared.entry_point`) and its fixed arguments."""
        from exo_bench.models.runtime.prepared import entry_point
        from exo_bench.models.newton_euler import derivatives_simd as ds

        ids = self.inverse_derivatives
        lead = (ids.nlinks, ids.g, ids.dim, ids.auto_simd() is not None)
        v, sq = np.empty(self._dof), np.empty(self._square)
        entry = entry_point(ds.checked_one, self._workspace(), *lead, True, v, v, v, sq, sq, sq)
        self._one = (entry, *lead)
        return self._one

    def _workspace(self) -> np.ndarray:
        """This thread's packed workspace of the one-sample entry, with the plans of its checks (made at its
        first call, then reused: :func:`exo_bench.models.newton_euler.derivatives_simd.one_workspace`)."""
        from exo_bench.models.newton_euler import derivatives_simd as ds

        ids = self.inverse_derivatives
        vplan, _, fplan, _ = self._checks or self._resolve_checks()
        simd = ids.auto_simd() is not None
        ws = self._local.ws = ds.one_workspace(ids.table, ids.mu, ids.dim, fplan, vplan, simd)
        return ws

    # ------------------------------------------------------------------ full Jacobians
    def inverse_dynamics(self, q, qd, qdd, check: bool = True):
        """``(dtau_dq, dtau_dqd, M)`` at the states: ``(S, dof, dof)`` each (``(dof, dof)`` for one
        ``(dof,)`` sample). ``M = dtau/dqdd``. Zero samples give ``(0, dof, dof)``. With ``check`` (the
        default) a state where forward dynamics is refused (``M`` singular or beyond the conditioning
        bound) is refused, naming the sample and the link (:meth:`_refuse_singular_states`); without it
        the values are finite there too (inverse dynamics is a polynomial in ``l``, ``cos`` and ``sin``)."""
        if (
            type(q) is _ND
            and q.ndim == 1
            and self._compiled_one
            and type(qd) is _ND
            and type(qdd) is _ND
            and q.dtype is _F8
            and qd.dtype is _F8
            and qdd.dtype is _F8
            and qd.ndim == 1
            and qdd.ndim == 1
        ):  # one sample: one compiled call, which checks the strides, the lengths and with check the values (_resolve_one)
            entry, n, g, dim, simd = self._one or self._resolve_one()
            ws = getattr(self._local, "ws", None)
            if ws is None:
                ws = self._workspace()
            sq = self._square
            out = np.empty(sq), np.empty(sq), np.empty(sq)
            if entry(ws, n, g, dim, simd, check, q, qd, qdd, *out) == 0:
                return out
        (q, qd, qdd), single = self._edge(_INVERSE, (q, qd, qdd), check)
        if not q.shape[0]:
            return tuple(np.zeros((0, self._dof, self._dof)) for _ in range(3))
        jacobians = self._inverse(q, qd, qdd)
        return (jacobians[0][0], jacobians[1][0], jacobians[2][0]) if single else jacobians

    def forward_dynamics(self, q, qd, tau, check: bool = True):
        """``(qdd, dqdd_dq, dqdd_dqd, Minv)`` at the states and forces: ``qdd (S, dof)``, the rest
        ``(S, dof, dof)`` (no sample axis for one ``(dof,)`` sample). ``Minv = dqdd/dtau``.

        With ``check`` (the default) the states are validated and they answer or refuse exactly as
        ``forward_dynamics`` does: a singular mass matrix raises
        :class:`exo_bench.models.mechanism.singularity.SingularConfigurationError` naming the link, one beyond
        the conditioning bound :class:`exo_bench.models.runtime.conditioning.NumericallySingularError` (the test
        every method shares), and an answer that is not finite is refused, never returned. Without
        ``check`` only the arrays are checked, and the mechanism itself: a link that moves no mass
        (``mu`` singular at every configuration) is refused either way."""
        (q, qd, tau), single = self._edge(_FORWARD, (q, qd, tau), check)
        if not q.shape[0]:
            d = self._dof
            return (np.zeros((0, d)), *(np.zeros((0, d, d)) for _ in range(3)))
        if self._fused_forward:
            out = self._forward_all(q, qd, tau)
        else:
            qdd = self._accelerations(q, qd, tau)
            out = (qdd, *self._forward_jacobians(q, qd, qdd, tau))
        if check and not np.isfinite(out[0].sum() + out[1].sum() + out[2].sum() + out[3].sum()):
            self._finite(out, ("qdd", "dqdd_dq", "dqdd_dqd", "Minv"))  # names what is not finite (or finds all finite)
        return _sample_of(out) if single else tuple(out)

    # ------------------------------------------------------------------ directional derivatives
    def inverse_dynamics_jvp(self, q, qd, qdd, dq, dqd, dqdd, check: bool = True):
        """``dtau = dtau/dq dq + dtau/dqd dqd + M dqdd``, ``(S, dof)``: forward mode through the passes,
        O(n) per sample (:func:`exo_bench.models.newton_euler.products.inverse_jvp`)."""
        arrays, single = self._edge(_INVERSE_JVP, (q, qd, qdd, dq, dqd, dqdd), check)
        out = self._products("jvp", *arrays)
        if check and not np.isfinite(out).all():
            self._finite_inverse(_INVERSE_JVP[0], (out,), ("dtau",))
        return out[0] if single else out

    def inverse_dynamics_vjp(self, q, qd, qdd, w, check: bool = True):
        """``(w^T dtau/dq, w^T dtau/dqd, w^T M)``, ``(S, dof)`` each: reverse mode through the passes,
        O(n) per sample (:func:`exo_bench.models.newton_euler.products.inverse_vjp`)."""
        arrays, single = self._edge(_INVERSE_VJP, (q, qd, qdd, w), check)
        out = self._products("vjp", *arrays)
        if check and not np.isfinite(out).all():
            self._finite_inverse(_INVERSE_VJP[0], out, ("w_dtau_dq", "w_dtau_dqd", "w_M"))
        return _sample_of(out) if single else tuple(out)

    def forward_dynamics_jvp(self, q, qd, tau, dq, dqd, dtau, check: bool = True):
        """``(qdd, dqdd)`` with ``dqdd = M^-1 (dtau - dID/dq dq - dID/dqd dqd)`` at ``qdd = FD(q, qd, tau)``:
        O(n) per sample; refuses what :meth:`forward_dynamics` refuses."""
        (q, qd, tau, dq, dqd, dtau), single = self._edge(_FORWARD_JVP, (q, qd, tau, dq, dqd, dtau), check)
        qdd = self._accelerations(q, qd, tau)
        rhs = dtau - self._products("jvp", q, qd, qdd, dq, dqd, np.zeros_like(q))
        out = (qdd, self._solve(q, rhs[:, :, None])[:, :, 0])
        if check:
            self._finite(out, ("qdd", "dqdd"))
        return _sample_of(out) if single else tuple(out)

    def forward_dynamics_vjp(self, q, qd, tau, w, check: bool = True):
        """``(qdd, w^T dqdd/dq, w^T dqdd/dqd, w^T M^-1)`` at ``qdd = FD(q, qd, tau)``: with ``u = M^-1 w``
        (``M`` symmetric), ``-u^T dID/dq``, ``-u^T dID/dqd`` and ``u``. O(n) per sample."""
        (q, qd, tau, w), single = self._edge(_FORWARD_VJP, (q, qd, tau, w), check)
        qdd = self._accelerations(q, qd, tau)
        u = self._solve(q, w[:, :, None])[:, :, 0]
        wq, wqd, _ = self._products("vjp", q, qd, qdd, np.ascontiguousarray(u))
        out = (qdd, -wq, -wqd, u)
        if check:
            self._finite(out, ("qdd", "w_dqdd_dq", "w_dqdd_dqd", "w_Minv"))
        return _sample_of(out) if single else tuple(out)


def _sample_of(out) -> tuple:
    """Sample 0 of each result (the answer of one ``(dof,)`` sample); no generator: the calls count their Python frames."""
    first = []
    for x in out:
        first.append(x[0])
    return tuple(first)


def _one_sample(q: Any) -> bool:
    """Whether ``q`` is one sample ``(dof,)`` (False for what numpy cannot shape: ragged rows)."""
    try:
        return np.ndim(q) == 1
    except ValueError:
        return False


def derivatives_of(mechanism: Mechanism, method: str, source: str | None = None, **options: Any) -> Derivatives:
    """The derivatives of ``mechanism``'s equations for a prepared model of ``method``
    (:attr:`exo_bench.models.runtime.prepared.PreparedModel.derivatives` builds them with the facts of its class)."""
    return Derivatives(mechanism, method, source, **options)
