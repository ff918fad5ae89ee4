"""The kernels of the matrix family (``matrix``, ``matrix-factored``, ``recurrence``), as objects
(:class:`~exo_bench.models.kernels.Kernel`): the tuples below are what each method's MethodSpec and
prepared-model class list. Each ``load`` binds a kernel to one prepared model of
:mod:`exo_bench.matrix_method.prepared` (its ``kernel_args``, ``serial_kernel``, ``parallel_kernel``,
``batch_kernel``), importing the compiled code only then: importing this module imports no numba.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exo_bench.models.kernels import BATCH, NUMBA_BYTES, ONE_SAMPLE, Entries, Kernel, entry_point
from exo_bench.models.unchecked import _may_overlap

#: The calls a kernel of inverse dynamics alone serves where mass matrix and bias forces are derived
#: from it (matrix-factored, :func:`exo_bench.models.prepared.terms_from_inverse_dynamics`).
_DERIVED = ("inverse_dynamics", "bias_forces", "mass_matrix", "mass_matrix_and_bias", "forward_dynamics")
_F8 = np.dtype(np.float64)


def _one_sample(model: Any) -> Entries:
    """The serial numba kernel on one sample, ``serial_kernel(*kernel_args, q, qd, qdd, out)``, through
    its compiled entry point for C-ordered float64 arrays (the only ones it is given)."""
    args, v = model.kernel_args, np.empty(model.dof)
    kernel = entry_point(model.serial_kernel, *args, v, v, v, v)

    def one(q, qd, qdd, out):
        kernel(*args, q, qd, qdd, out)
        return out

    return Entries(inverse_one=one)


def _drivers(model: Any) -> Entries:
    """The numba drivers: one sample serial, a batch on numba's threads from a size on."""
    from exo_bench.matrix_method.numba_kernels.common import run

    def whole(q, qd, qdd, out=None):
        o = model._results.empty(q.shape) if out is None else out  # C-ordered: reshape(-1) is a view
        args = (*model.kernel_args, q.reshape(-1), qd.reshape(-1), qdd.reshape(-1), o.reshape(-1))
        run(model.serial_kernel, model.parallel_kernel, args, q.shape[0])
        return o

    return _one_sample(model).merged(Entries(inverse_whole=whole, inverse_chunk=whole))


def _simd(model: Any) -> Entries:
    """matrix-factored's batches: the kernel that vectorises across samples, in blocks over threads."""
    from exo_bench.models.simd_blocks import run

    def whole(q, qd, qdd, out=None):
        o = model._results.empty(q.shape) if out is None else out
        flat = (q.reshape(-1), qd.reshape(-1), qdd.reshape(-1), o.reshape(-1))
        run(model.batch_kernel, model.kernel_args[0], *flat, q.shape[0], scratch=model.batch_scratch)
        return o

    return Entries(inverse_whole=whole, inverse_chunk=whole)


def _declined(*args: Any, **kw: Any) -> None:
    """The compiled lean call's fallback: the call is not one it takes (the base class goes on)."""
    return None


def _lean(model: Any) -> Entries:
    """matrix-factored's one sample, nothing else around the arithmetic
    (:mod:`exo_bench.matrix_method.numba_kernels.lean`): the compiled wrapper where setup.py built it,
    else the kernel's compiled entry point behind the checks unboxing trusts; the per-sample kernel
    through numba's dispatcher where neither takes the arrays (the same arithmetic)."""
    from exo_bench.matrix_method.numba_kernels import lean
    from exo_bench.models.states import validation_plan

    dim, params = model.mechanism.dim, model.kernel_args[0]
    if not hasattr(lean.KERNELS[dim], "compile"):  # NUMBA_DISABLE_JIT: no entry point to resolve
        return _one_sample(model)
    plan = validation_plan(model.mechanism)  # the C wrapper takes check=True too, validating first
    fast = lean.c_call(dim, params, _declined, model.dof, plan) or _python_lean(lean.entry(dim, params), params)
    serial = model.serial_kernel

    def one(q, qd, qdd, out):
        if fast(q, qd, qdd, False, out) is None:
            serial(params, q, qd, qdd, out)
        return out

    return Entries(lean=fast, inverse_one=one)


def _python_lean(entry: Any, params: np.ndarray) -> Any:
    """The lean call in Python around the kernel's compiled entry point, ``check=False`` only: what
    unboxing trusts (dimensions, dtype, a writable ``out`` apart from the inputs) checked here, the rest
    in compiled code."""

    def call(q, qd, qdd, check, out):
        try:
            if (
                check is False  # check=True: declined (the checked path validates first)
                and q.ndim == 1
                and qd.ndim == 1
                and qdd.ndim == 1
                and out.ndim == 1
                and q.dtype is _F8
                and qd.dtype is _F8
                and qdd.dtype is _F8
                and out.dtype is _F8
                and out.flags.writeable
                and not (_may_overlap(out, q) or _may_overlap(out, qd) or _may_overlap(out, qdd))
                and entry(params, q, qd, qdd, out)
            ):
                return out
        except AttributeError:
            pass
        return None

    return call


def _cholesky_forward(model: Any) -> Entries:
    """matrix-factored's forward dynamics of one sample in compiled code, checked in the same call
    (:mod:`exo_bench.matrix_method.numba_kernels.cholesky_forward`: ``h`` and the Cholesky factor of the
    coupling, computed here once per model); where that declines (``M`` singular), the model's
    ``check_regular`` names why, else the numpy route (``mass_matrix_and_bias``, ``cholesky_solve``)
    decides. Nothing where the coupling itself is not positive definite (the checks refuse the mechanism)."""
    from exo_bench.matrix_method.numba_kernels import cholesky_forward_c as c
    from exo_bench.matrix_method.numba_kernels.cholesky_forward import entries
    from exo_bench.models.forward_check import checked_entry, lean_entry

    try:
        lc = np.ascontiguousarray(np.linalg.cholesky(model.coupling))
    except np.linalg.LinAlgError:
        return Entries()
    e, params, numpy_route = entries(), model.kernel_args[0], model._forward_dynamics

    def forward_one(q, qd, tau, out):
        if not e.forward_sample(params, lc, q, qd, tau, out):  # M singular: named by the checks, else numpy's
            model.check_regular(q.reshape(1, -1))
            out[...] = numpy_route(q[None], qd[None], tau[None])[0]
        return out

    fused = checked_entry(model, e.checked_forward, (params, lc), forward_one)
    lean = lean_entry(model, c.checked_forward_c, lambda plan: c.packed(params, lc, plan))
    return Entries(forward_one=forward_one, forward_checked=fused, forward_lean=lean)


def _numpy_tiles(model: Any) -> Entries:
    """The numpy reference: the model's own vectorised code, ``tile`` samples at a time."""
    return Entries(inverse_chunk=model.numpy_inverse_dynamics)


_NUMPY_THREADS = "one thread (numpy's, BLAS not used)"
_NUMBA_THREADS = (
    "one thread for one sample; a batch splits over numba's threads from a size on (numba_kernels.common.run)"
)


def _numba(name: str, cost: str, speed: float, compile_seconds: float) -> Kernel:
    return Kernel(
        "numba",
        "numba",
        ("inverse_dynamics",),
        (ONE_SAMPLE, BATCH),
        _NUMBA_THREADS,
        f"{name}'s sample_seconds times {speed:g} ({cost})",
        speed=speed,
        compile_seconds=compile_seconds,
        runtime_bytes=NUMBA_BYTES,
        load=_drivers,
    )


def _numpy(name: str, computes: tuple[str, ...] = ("inverse_dynamics",)) -> Kernel:
    return Kernel(
        "numpy",
        "numpy",
        computes,
        (ONE_SAMPLE, BATCH),
        _NUMPY_THREADS,
        f"{name}'s sample_seconds, in chunks of chunk_samples",
        load=_numpy_tiles,
    )


# Compile times measured on the 2-core machine with other jobs running (matrix-factored 1.6-2.9 s,
# matrix 5.4-7.5 s, recurrence 4.2-7.7 s), rounded up: the kernels of one option compile together.
MATRIX_KERNELS = (
    _numba("MATRIX", "measured at 0.4 to 0.7 of the numpy figures: matrix 2D/3D n = 60, 100, 300", 0.5, 10.0),
    _numpy("MATRIX"),
)
RECURRENCE_KERNELS = (
    _numba("RECURRENCE", "the formulas are the compiled kernel's", 1.0, 10.0),
    _numpy("RECURRENCE"),
)
MATRIX_FACTORED_KERNELS = (
    Kernel(
        "simd",
        "numba",
        _DERIVED,
        (BATCH,),
        "blocks of samples split over a Python thread pool from PARALLEL_MIN_ELEMENTS state elements "
        "(models.simd_blocks.run), each thread with its scratch (ThreadScratch)",
        "MATRIX_FACTORED's sample_seconds (the SIMD kernels, batches of 2000)",
        compile_seconds=4.0,
        runtime_bytes=NUMBA_BYTES,
        load=_simd,
    ),
    Kernel(
        "lean",
        "numba",
        ("inverse_dynamics",),
        (ONE_SAMPLE,),
        "one thread: the calling one",
        "below MATRIX_FACTORED's call_seconds: one sample's arithmetic and a few checks in C (the per-sample "
        "kernel of numba_kernels.factored as a cfunc)",
        compile_seconds=4.0,
        runtime_bytes=NUMBA_BYTES,
        load=_lean,
    ),
    Kernel(
        "cholesky-forward",
        "numba",
        ("forward_dynamics",),
        (ONE_SAMPLE,),
        "one thread: the calling one",
        "one sample only, O(n^2) (h by the factored kernel, M = R^T (C x I) R solved through the Cholesky "
        "factor of C): below MATRIX_FACTORED's call_seconds (its cost formulas time batches)",
        compile_seconds=4.0,
        runtime_bytes=NUMBA_BYTES,
        load=_cholesky_forward,
    ),
    _numpy("MATRIX_FACTORED", _DERIVED),
)

#: Why matrix-paper's results are known to be wrong, in one line: its prepared-model class's ``known_wrong``
#: and its MethodSpec's (here, beside the kernels both list, so that the method table imports no numba).
PRINTED_EQ18_WRONG = "eq. (18) as printed has misprints: 3D results are wrong by design (reports/errata.md)"
