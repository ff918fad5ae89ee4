"""The kernels of ``newton-euler``, as objects (:class:`~exo_bench.models.runtime.prepared.Kernel`):
:data:`NEWTON_EULER_KERNELS` is what its MethodSpec and :class:`~exo_bench.models.newton_euler.prepared.NewtonEuler`
list. Each ``load`` binds a kernel to one prepared model (its ``table``, ``kernel_args``,
``batch_kernel``), importing the compiled code only then: importing this module imports no numba.
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np

from exo_bench.models.runtime.prepared import BATCH, NUMBA_BYTES, ONE_SAMPLE, Entries, Kernel, entry_point, lean_kernel

_CALLS = ("inverse_dynamics", "forward_dynamics", "bias_forces", "mass_matrix_and_bias")


def _passes(model: Any, forward: bool, simd_from: int | None):
    """A batch of the compiled passes into ``out`` (or a new array): the SIMD kernel from
    ``simd_from`` samples on (inverse dynamics), else the per-sample drivers on numba's threads."""
    from exo_bench.models.newton_euler import compiled
    from exo_bench.models.machine.numba_runtime import run
    from exo_bench.models.machine.simd_blocks import run as run_simd

    args = (model.table, model._g, model._dim, forward)

    def whole(q, qd, y, out=None):
        o = model._results.empty(q.shape) if out is None else out  # C-ordered whatever q is: a view
        flat = (q.reshape(-1), qd.reshape(-1), y.reshape(-1), o.reshape(-1))
        samples = q.shape[0]
        if simd_from is not None and samples >= simd_from:
            run_simd(model.batch_kernel, model.batch_args, *flat, samples, scratch=model.batch_scratch)
        else:
            run(compiled.newton_euler, compiled.newton_euler_parallel, (*args, *flat), samples)
        return o

    return whole


def _per_sample(model: Any) -> Entries:
    """The compiled passes of one sample (serial, through their compiled entry point for C-ordered
    float64 arrays, the only ones they are given), and forward dynamics of any batch."""
    inverse, kernel = model.kernel_args, _serial_entry(model)

    def inverse_one(q, qd, qdd, out):
        kernel(*inverse, q, qd, qdd, out)
        return out

    batch = _passes(model, True, None)
    return Entries(inverse_one=inverse_one, forward_one=_forward_one(model, kernel), forward_chunk=batch)


def _serial_entry(model: Any) -> Any:
    """The compiled entry point of the model's serial passes for C-ordered float64 arrays (the flag
    ``forward`` is an argument: one entry serves both directions)."""
    v = np.empty(model.dof)
    return entry_point(model.serial_kernel, *model.kernel_args, v, v, v, v)


def _forward_one(model: Any, kernel: Any) -> Any:
    """``forward_one(q, qd, tau, out)``: forward dynamics of one sample by the serial passes ``kernel``
    (:func:`_serial_entry`); with ``check=False`` a singular state (a division by zero in the passes)
    is named as the checks name it."""
    forward = model._forward_args

    def forward_one(q, qd, tau, out):
        try:
            kernel(*forward, q, qd, tau, out)
        except ZeroDivisionError:
            model.check_regular(q.reshape(1, -1))
            raise
        return out

    return forward_one


def _tree_forward(model: Any) -> Entries:
    """Newton-euler's checked forward dynamics of one sample: the compiled common-case checks and its
    serial forward passes in one call (:mod:`exo_bench.models.newton_euler.forward_fused`); near a
    bound the model's exact ``check_regular`` decides and names why, then the same passes run. Its
    ``forward_fast``: the same in the public call's one compiled call, the states' checks included."""
    from exo_bench.models.runtime.forward_check import checked_entry
    from exo_bench.models.newton_euler.forward_fused import batch_entry, entry, lean_entry
    from exo_bench.models.states.states import validation_plan

    forward_one = _forward_one(model, _serial_entry(model))  # the per-sample kernel's (the same passes)
    fused = checked_entry(model, entry(), (model.table,), forward_one)
    passes, checked = _passes(model, True, None), batch_entry()
    model._forward_checks or model._resolve_forward_checks()  # the checks' plan, once per model
    table, plan = model.table, model.forward_plan

    def whole(q, qd, tau, out, check):
        """A batch: with ``check`` the checks' common case and the passes sample by sample in one compiled
        call (None where a sample does not clear them: the checked path decides), else the passes."""
        if not check:
            return passes(q, qd, tau, out)
        o = model._results.empty(q.shape) if out is None else out
        return o if checked(table, plan, q, qd, tau, o) < 0 else None

    compiled = lean_entry(model.table)
    if compiled is None:  # NUMBA_DISABLE_JIT
        return Entries(forward_checked=fused, forward_whole=whole)
    fast = partial(compiled, table, plan, validation_plan(model.mechanism))
    return Entries(forward_checked=fused, forward_fast=fast, forward_whole=whole)


def _simd(model: Any) -> Entries:
    """Batches of inverse dynamics: SIMD from :data:`~exo_bench.models.newton_euler.simd.MIN_SAMPLES` on."""
    from exo_bench.models.newton_euler.simd import MIN_SAMPLES

    batch = _passes(model, False, MIN_SAMPLES)
    return Entries(inverse_whole=batch, inverse_chunk=batch)


def _lean(model: Any) -> Entries:
    """One sample in one compiled call, checks included (:mod:`exo_bench.models.newton_euler.compiled`)."""
    from exo_bench.models.newton_euler import compiled
    from exo_bench.models.states.states import validation_plan

    fast = compiled.entry(model.table)
    if fast is None:  # NUMBA_DISABLE_JIT
        return Entries()
    return Entries(inverse_fast=partial(fast, model.table, float(model._g), validation_plan(model.mechanism)))


def _numpy(model: Any) -> Entries:
    return Entries(inverse_chunk=model.numpy_inverse_dynamics, forward_chunk=model.numpy_forward_dynamics)


# the cost formulas' figures (exo_bench/api/cost_formulas.py NEWTON_EULER) are the numpy kernel's; the
# compiled kernels run at 0.07-0.13 of them. Compile time 11.7 s (serial and parallel, one dim) on the
# busy machine, rounded up.
#: Checked forward dynamics of one sample: the conditioning checks' common case and newton-euler's O(n)
#: passes in one compiled call (models/newton_euler/forward_check.py). Newton-euler's own: another
#: method's forward dynamics stays its own (a Cholesky solve of its M and h), so that the methods
#: cross-validate each other and a method's name says what runs.
TREE_FORWARD = Kernel(
    "tree-forward",
    "numba",
    ("forward_dynamics",),
    (ONE_SAMPLE,),
    "one thread: the calling one",
    "one sample only, O(n): below the method's call_seconds (its cost formulas time batches)",
    compile_seconds=10.0,  # the serial driver for one dimension: 9.2 s measured on the busy machine
    runtime_bytes=NUMBA_BYTES,
    load=_tree_forward,
)


NEWTON_EULER_KERNELS = (
    Kernel(
        "numba",
        "numba",
        _CALLS,
        (ONE_SAMPLE, BATCH),
        "one thread for one sample; forward dynamics and batches below MIN_SAMPLES split over numba's "
        "threads from a size on (models.numba_runtime.run)",
        "NEWTON_EULER's sample_seconds times 0.12",
        speed=0.12,
        compile_seconds=15.0,
        runtime_bytes=NUMBA_BYTES,
        load=_per_sample,
    ),
    TREE_FORWARD,
    Kernel(
        "simd",
        "numba",
        ("inverse_dynamics", "bias_forces", "mass_matrix_and_bias"),
        (BATCH,),
        "blocks of samples split over a Python thread pool (models.simd_blocks.run), each thread with its scratch",
        "NEWTON_EULER's sample_seconds times 0.12 (batches of at least MIN_SAMPLES)",
        speed=0.12,
        compile_seconds=15.0,
        runtime_bytes=NUMBA_BYTES,
        load=_simd,
    ),
    lean_kernel(
        "below NEWTON_EULER's call_seconds: one sample's checks and passes in one compiled call (the "
        "per-sample inverse pass of compiled.py behind models/newton_euler/compiled.py's entry)",
        speed=0.12,
        compile_seconds=15.0,
        load=_lean,
    ),
    Kernel(
        "numpy",
        "numpy",
        _CALLS,
        (ONE_SAMPLE, BATCH),
        "one thread (numpy's)",
        "NEWTON_EULER's sample_seconds, in chunks of chunk_samples",
        load=_numpy,
    ),
)
