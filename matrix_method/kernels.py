"""The kernels of the matrix family (``matrix``, ``matrix-factored``, ``recurrence``), as objects
(:class:`~exo_bench.models.runtime.prepared.Kernel`): the tuples below are what each method's MethodSpec and
prepared-model class list. Each ``load`` binds a kernel to one prepared model of
:mod:`exo_bench.matrix_method.prepared` (its ``kernel_args``, ``serial_kernel``, ``parallel_kernel``,
``batch_kernel``), importing the compiled code only then: importing this module imports no numba.
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np

from exo_bench.models.runtime.prepared import BATCH, NUMBA_BYTES, ONE_SAMPLE, Entries, Kernel, entry_point, lean_kernel

#: The calls a kernel of inverse dynamics alone serves where mass matrix and bias forces are derived
#: from it (matrix-factored, :func:`exo_bench.models.runtime.prepared.terms_from_inverse_dynamics`).
_DERIVED = ("inverse_dynamics", "bias_forces", "mass_matrix", "mass_matrix_and_bias", "forward_dynamics")


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
    from exo_bench.models.machine.simd_blocks import run

    def whole(q, qd, qdd, out=None):
        o = model._results.empty(q.shape) if out is None else out
        flat = (q.reshape(-1), qd.reshape(-1), qdd.reshape(-1), o.reshape(-1))
        run(model.batch_kernel, model.kernel_args[0], *flat, q.shape[0], scratch=model.batch_scratch)
        return o

    return Entries(inverse_whole=whole, inverse_chunk=whole)


def _lean(model: Any) -> Entries:
    """matrix-factored's one sample, nothing else around the arithmetic
    (:mod:`exo_bench.matrix_method.numba_kernels.lean`): its compiled validate-and-compute entry, bound to
    the model's parameters and validation plan, and the per-sample kernel behind it (a mechanism too large
    for the entry's stack scratch; the same arithmetic)."""
    from exo_bench.matrix_method.numba_kernels import lean
    from exo_bench.models.machine.numba_runtime import jit_disabled
    from exo_bench.models.states.states import validation_plan

    if jit_disabled():  # NUMBA_DISABLE_JIT: no entry point to resolve, the checked path runs
        return _one_sample(model)
    dim, params = model.mechanism.dim, model.kernel_args[0]
    fast = partial(lean.entry(dim, params), params, validation_plan(model.mechanism))
    serial = model.serial_kernel

    def one(q, qd, qdd, out):
        if fast(q, qd, qdd, out, False):
            serial(params, q, qd, qdd, out)
        return out

    return Entries(inverse_fast=fast, inverse_one=one)


def _cholesky_forward(model: Any) -> Entries:
    """matrix-factored's forward dynamics of one sample in compiled code, checked in the same call
    (:mod:`exo_bench.matrix_method.numba_kernels.cholesky_forward`: ``h`` and the Cholesky factor of the
    coupling, computed here once per model); where that declines (``M`` singular), the model's
    ``check_regular`` names why, else the numpy route (``mass_matrix_and_bias``, ``cholesky_solve``)
    decides. Nothing where the coupling itself is not positive definite (the checks refuse the mechanism)."""
    from exo_bench.matrix_method.numba_kernels.cholesky_forward import entries, entry
    from exo_bench.models.runtime.forward_check import checked_entry
    from exo_bench.models.machine.numba_runtime import jit_disabled
    from exo_bench.models.states.states import validation_plan

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
    model._forward_checks or model._resolve_forward_checks()  # the checks' plan, once per model
    plan, batch = model.forward_plan, e.forward_batch

    def whole(q, qd, tau, out, check):
        """A batch, sample by sample in one compiled call (with ``check`` the checks' common case too);
        None where a sample is not done (the checked path, the numpy route, then decides and names it)."""
        o = model._results.empty(q.shape) if out is None else out
        return o if batch(params, lc, plan, q, qd, tau, o, check) < 0 else None

    if jit_disabled():
        return Entries(forward_one=forward_one, forward_checked=fused, forward_whole=whole)
    fast = partial(entry(params, lc), params, lc, plan, validation_plan(model.mechanism))
    return Entries(forward_one=forward_one, forward_checked=fused, forward_fast=fast, forward_whole=whole)


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
    lean_kernel(
        "below MATRIX_FACTORED's call_seconds: one sample's checks and arithmetic in one compiled call (the "
        "per-sample kernel of numba_kernels.factored behind numba_kernels.lean's entry)",
        compile_seconds=4.0,
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
