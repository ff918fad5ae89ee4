"""The kernels of ``newton-euler``, as objects (:class:`~exo_bench.models.kernels.Kernel`):
:data:`NEWTON_EULER_KERNELS` is what its MethodSpec and :class:`~exo_bench.models.newton_euler.prepared.NewtonEuler`
list. Each ``load`` binds a kernel to one prepared model (its ``table``, ``kernel_args``,
``batch_kernel``), importing the compiled code only then: importing this module imports no numba.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exo_bench.models.kernels import BATCH, NUMBA_BYTES, ONE_SAMPLE, Entries, Kernel, entry_point

_CALLS = ("inverse_dynamics", "forward_dynamics", "bias_forces", "mass_matrix_and_bias")


def _passes(model: Any, forward: bool, simd_from: int | None):
    """A batch of the compiled passes into ``out`` (or a new array): the SIMD kernel from
    ``simd_from`` samples on (inverse dynamics), else the per-sample drivers on numba's threads."""
    from exo_bench.models.newton_euler import compiled
    from exo_bench.models.numba_runtime import run
    from exo_bench.models.simd_blocks import run as run_simd

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
    inverse, forward, v = model.kernel_args, model._forward_args, np.empty(model.dof)
    kernel = entry_point(model.serial_kernel, *inverse, v, v, v, v)  # the flag `forward` is an argument

    def inverse_one(q, qd, qdd, out):
        kernel(*inverse, q, qd, qdd, out)
        return out

    def forward_one(q, qd, tau, out):
        kernel(*forward, q, qd, tau, out)
        return out

    batch = _passes(model, True, None)
    return Entries(inverse_one=inverse_one, forward_one=forward_one, forward_whole=batch, forward_chunk=batch)


def _simd(model: Any) -> Entries:
    """Batches of inverse dynamics: SIMD from :data:`~exo_bench.models.newton_euler.simd.MIN_SAMPLES` on."""
    from exo_bench.models.newton_euler.simd import MIN_SAMPLES

    batch = _passes(model, False, MIN_SAMPLES)
    return Entries(inverse_whole=batch, inverse_chunk=batch)


def _numpy(model: Any) -> Entries:
    return Entries(inverse_chunk=model.numpy_inverse_dynamics, forward_chunk=model.numpy_forward_dynamics)


# the cost formulas' figures (exo_bench/api/cost_formulas.py NEWTON_EULER) are the numpy kernel's; the
# compiled kernels run at 0.07-0.13 of them. Compile time 11.7 s (serial and parallel, one dim) on the
# busy machine, rounded up.
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
