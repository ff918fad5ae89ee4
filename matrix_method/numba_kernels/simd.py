"""Method ``matrix-factored``, compiled to vectorise across samples: the batched path.

The per-sample kernel (:mod:`exo_bench.matrix_method.numba_kernels.factored`) computes each sample whole, with
libm's ``sin`` and ``cos`` per angle: nothing is vectorised. This kernel computes :data:`LANES`
samples at once, each step a loop over the samples that LLVM turns into SIMD instructions:

1. **transpose in**: a block of the user's ``(samples, dof)`` states (flat, C-ordered: they go in
   unchanged) into per-link rows of :data:`LANES` samples, ``W[(j * ROWS + r) * LANES + s]``: a whole
   block in tiles of 8 samples x 8 columns through SIMD registers, a partial block one row of ``W`` at
   a time (:func:`exo_bench.models.simd_blocks.block_transposes`). exo5-3d, 10,000 samples, one
   thread, the whole kernel: 44.3 ns per sample against 51.7 with the loops alone (whose column
   reads LLVM makes gathers), the quiet machine, one run each;
2. **per link j**: ``sin``/``cos`` of its angles in branch-free arithmetic
   (:func:`exo_bench.matrix_method.numba_kernels.fast_trig.sincos_reduced`; the angles beyond its range, and NaN, are
   redone with libm by a scalar loop that only they enter) and ``kappa_j``
   (:func:`exo_bench.matrix_method.closed_forms.factored.kappa_3d`);
3. ``f_i = sum_j c_ij kappa_j``: one multiply-add per sample per (i, j, axis), summed in the same
   order as the per-sample kernel;
4. **per link i**: the forces (:func:`exo_bench.matrix_method.closed_forms.factored.forces_3d`), then **transpose
   out** into the user's ``(samples, dof)`` result (tiles again for a whole block).

A ``(dof, samples)`` entry (copying rows of the caller's arrays instead of transposing) was tried
and measured 3x slower here: a block then reads 45 rows of exo5-3d at once (and writes 15), more
streams than the hardware prefetchers follow, each row on its own page.

A whole block calls the steps with ``m = LANES``, a constant: the steps are inlined and every loop
over the samples compiles with a fixed trip count (no remainder loop, no runtime checks); exo5-3d,
10,000 samples, one thread: 51.4 against 64.9 ns per sample with ``m`` at run time (the other core
running the benchmark sweep). The last, partial block runs with ``m`` at run time.

The physics is the element functions the other kernels call; this file only arranges the loops.
The rows of one link sit at constant distances (multiples of :data:`LANES`) in one scratch array,
so LLVM proves that a loop's stores do not overlap its loads without being told (no ``prange``
needed for the no-aliasing knowledge); steps 3 and 4 read one scratch array and write another,
which LLVM checks once per loop at run time. Unit stride everywhere but in the two transposes.

Against the per-sample kernel the result differs only by the ``sin``/``cos`` (at most :data:`~exo_bench.models.fast_trig.ULPS` ulp
each, :mod:`exo_bench.matrix_method.numba_kernels.fast_trig`): the same operations in the same order otherwise.

**Threads.** :func:`run` splits a batch of at least :data:`exo_bench.models.simd_blocks.PARALLEL_MIN_ELEMENTS` state elements
(samples x dof) over ``numba.get_num_threads()`` threads (the caller's and a pool's), which pull shares of it and
call the serial kernel on each (it releases the GIL): numba's threading layer is never entered, so the batch path runs
at the same speed whichever layer numba picked or the user started first (OpenMP's spinning
threads cost 7-8 ms per call of a ``prange`` kernel after a user's code started them).

numba's on-disk cache of these kernels is keyed on their folder, the element functions' files and
the shared ``fast_trig.py``, ``simd_blocks.py`` and ``numba_threads.py`` (:mod:`exo_bench.models.numba_cache`):
an edit to any of them recompiles them.
"""

from __future__ import annotations

import math

from exo_bench.matrix_method.numba_kernels.common import JIT, njit
from exo_bench.matrix_method.closed_forms.factored import forces_2d, forces_3d, kappa_2d, kappa_3d
from exo_bench.matrix_method.numba_kernels.fast_trig import RANGE, sincos_reduced
from exo_bench.models.simd_blocks import (  # noqa: F401 - the shared layout, re-exported under its old names
    CF,
    CP,
    F0,
    F1,
    F2,
    FROWS,
    K0,
    K1,
    K2,
    L1,
    L1_2,
    L2,
    L2_2,
    LANES,
    LEN,
    LEN2,
    O0,
    O1,
    O2,
    PHI,
    PSI,
    ROWS,
    SF,
    SHARES_PER_THREAD,
    SP,
    U,
    V1,
    V2,
    W1,
    W2,
    _block_rows_in,
    _block_rows_out,
    _block_scratch,
    _rows_in,
    _rows_in_by_link,
    _rows_out,
    _rows_out_by_link,
    run,
)


@njit(**JIT)
def _compute_3d(p, m, W, F):
    """2-4. From the rows of ``W`` (``m`` samples) to the forces in ``F``, spatial."""
    n = p.shape[0]
    B = LANES
    outside = 0
    for j in range(n):  # 2. sin, cos, kappa_j
        w = j * ROWS * B
        for s in range(m):
            phi, psi = W[w + PHI * B + s], W[w + PSI * B + s]
            okf, okp = abs(phi) <= RANGE, abs(psi) <= RANGE
            sf, cf = sincos_reduced(phi if okf else 0.0)
            sp, cp = sincos_reduced(psi if okp else 0.0)
            outside += (0 if okf else 1) + (0 if okp else 1)
            W[w + CF * B + s], W[w + SF * B + s], W[w + CP * B + s], W[w + SP * B + s] = cf, sf, cp, sp
            W[w + K0 * B + s], W[w + K1 * B + s], W[w + K2 * B + s] = kappa_3d(
                W[w + LEN * B + s],
                W[w + W1 * B + s],
                W[w + V1 * B + s],
                W[w + L1 * B + s],
                W[w + W2 * B + s],
                W[w + V2 * B + s],
                W[w + L2 * B + s],
                cf,
                sf,
                cp,
                sp,
            )
    if outside:  #    libm for the angles beyond RANGE (and NaN)
        for j in range(n):
            w = j * ROWS * B
            for s in range(m):
                phi, psi = W[w + PHI * B + s], W[w + PSI * B + s]
                if not (abs(phi) <= RANGE and abs(psi) <= RANGE):
                    cf, sf, cp, sp = math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi)
                    W[w + CF * B + s], W[w + SF * B + s], W[w + CP * B + s], W[w + SP * B + s] = cf, sf, cp, sp
                    W[w + K0 * B + s], W[w + K1 * B + s], W[w + K2 * B + s] = kappa_3d(
                        W[w + LEN * B + s],
                        W[w + W1 * B + s],
                        W[w + V1 * B + s],
                        W[w + L1 * B + s],
                        W[w + W2 * B + s],
                        W[w + V2 * B + s],
                        W[w + L2 * B + s],
                        cf,
                        sf,
                        cp,
                        sp,
                    )
    for i in range(n):  # 3. f_i = sum_j c_ij kappa_j
        f = i * FROWS * B
        for s in range(m):
            F[f + F0 * B + s] = 0.0
            F[f + F1 * B + s] = 0.0
            F[f + F2 * B + s] = 0.0
        for j in range(n):
            c = p[i, j]
            w = j * ROWS * B
            for s in range(m):
                F[f + F0 * B + s] += c * W[w + K0 * B + s]
                F[f + F1 * B + s] += c * W[w + K1 * B + s]
                F[f + F2 * B + s] += c * W[w + K2 * B + s]
    for i in range(n):  # 4. the forces of link i
        f, w, gnu = i * FROWS * B, i * ROWS * B, p[i, n + 1] * p[i, n]
        for s in range(m):
            F[f + O0 * B + s], F[f + O1 * B + s], F[f + O2 * B + s] = forces_3d(
                W[w + LEN * B + s],
                W[w + CF * B + s],
                W[w + SF * B + s],
                W[w + CP * B + s],
                W[w + SP * B + s],
                F[f + F0 * B + s],
                F[f + F1 * B + s],
                F[f + F2 * B + s],
                gnu,
            )


@njit(**JIT)
def _compute_2d(p, m, W, F):
    """2-4. From the rows of ``W`` (``m`` samples) to the forces in ``F``, planar (the rows of the
    planar blocks: phi in row 0, l in row 1; the forces ``M_phi, F`` in ``O0, O1``)."""
    n = p.shape[0]
    B = LANES
    outside = 0
    for j in range(n):  # 2. sin, cos, kappa_j
        w = j * ROWS * B
        for s in range(m):
            phi = W[w + PHI * B + s]
            okf = abs(phi) <= RANGE
            sf, cf = sincos_reduced(phi if okf else 0.0)
            outside += 0 if okf else 1
            W[w + CF * B + s], W[w + SF * B + s] = cf, sf
            W[w + K0 * B + s], W[w + K1 * B + s] = kappa_2d(
                W[w + LEN2 * B + s],
                W[w + W1 * B + s],
                W[w + L1_2 * B + s],
                W[w + W2 * B + s],
                W[w + L2_2 * B + s],
                cf,
                sf,
            )
    if outside:  #    libm for the angles beyond RANGE (and NaN)
        for j in range(n):
            w = j * ROWS * B
            for s in range(m):
                phi = W[w + PHI * B + s]
                if not abs(phi) <= RANGE:
                    cf, sf = math.cos(phi), math.sin(phi)
                    W[w + CF * B + s], W[w + SF * B + s] = cf, sf
                    W[w + K0 * B + s], W[w + K1 * B + s] = kappa_2d(
                        W[w + LEN2 * B + s],
                        W[w + W1 * B + s],
                        W[w + L1_2 * B + s],
                        W[w + W2 * B + s],
                        W[w + L2_2 * B + s],
                        cf,
                        sf,
                    )
    for i in range(n):  # 3. f_i = sum_j c_ij kappa_j
        f = i * FROWS * B
        for s in range(m):
            F[f + F0 * B + s] = 0.0
            F[f + F1 * B + s] = 0.0
        for j in range(n):
            c = p[i, j]
            w = j * ROWS * B
            for s in range(m):
                F[f + F0 * B + s] += c * W[w + K0 * B + s]
                F[f + F1 * B + s] += c * W[w + K1 * B + s]
    for i in range(n):  # 4. the forces of link i
        f, w, gnu = i * FROWS * B, i * ROWS * B, p[i, n + 1] * p[i, n]
        for s in range(m):
            F[f + O0 * B + s], F[f + O1 * B + s] = forces_2d(
                W[w + LEN2 * B + s], W[w + CF * B + s], W[w + SF * B + s], F[f + F0 * B + s], F[f + F1 * B + s], gnu
            )


@njit(**JIT)
def simd_3d(p, q, qd, qdd, o, start, stop, S=None):
    """Samples ``start .. stop - 1`` of the flat spatial ``(samples, dof)`` states into ``o``,
    :data:`LANES` at a time; ``S``: the scratch of ``_block_scratch(n, 3)`` (kept per thread, :class:`exo_bench.models.simd_blocks.ThreadScratch`), or None to allocate it here."""
    n = p.shape[0]
    if S is None:
        W, F, T = _block_scratch(n, 3)
    else:
        W, F, T = S
    for s0 in range(start, stop, LANES):
        if stop - s0 >= LANES:  # a whole block: the trip counts are the constant LANES (module docstring)
            _block_rows_in(q, qd, qdd, s0, LANES, n, 3, W, T)
            _compute_3d(p, LANES, W, F)
            _block_rows_out(o, s0, LANES, n, 3, F, T)
        else:
            m = stop - s0
            _block_rows_in(q, qd, qdd, s0, m, n, 3, W, T)
            _compute_3d(p, m, W, F)
            _block_rows_out(o, s0, m, n, 3, F, T)


@njit(**JIT)
def simd_2d(p, q, qd, qdd, o, start, stop, S=None):
    """Samples ``start .. stop - 1`` of the flat planar ``(samples, dof)`` states into ``o``,
    :data:`LANES` at a time; ``S``: the scratch of ``_block_scratch(n, 2)`` (kept per thread, :class:`exo_bench.models.simd_blocks.ThreadScratch`), or None to allocate it here."""
    n = p.shape[0]
    if S is None:
        W, F, T = _block_scratch(n, 2)
    else:
        W, F, T = S
    for s0 in range(start, stop, LANES):
        if stop - s0 >= LANES:  # a whole block: the trip counts are the constant LANES (module docstring)
            _block_rows_in(q, qd, qdd, s0, LANES, n, 2, W, T)
            _compute_2d(p, LANES, W, F)
            _block_rows_out(o, s0, LANES, n, 2, F, T)
        else:
            m = stop - s0
            _block_rows_in(q, qd, qdd, s0, m, n, 2, W, T)
            _compute_2d(p, m, W, F)
            _block_rows_out(o, s0, m, n, 2, F, T)


#: dim -> the kernel ``(params, q, qd, qdd, o, start, stop[, S])`` on flat states
KERNELS = {2: simd_2d, 3: simd_3d}
#: ``scratch(n, blocks) -> (W, F, T)``: the kernels' scratch, the ``S`` they take
scratch = _block_scratch
