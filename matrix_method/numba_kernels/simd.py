"""Method ``matrix-factored``, compiled to vectorise across samples: the batched path.

The per-sample kernel (:mod:`exo_bench.matrix_method.numba_kernels.factored`) computes each sample whole, with
libm's ``sin`` and ``cos`` per angle: nothing is vectorised. This kernel computes :data:`LANES`
samples at once, each step a loop over the samples that LLVM turns into SIMD instructions:

1. **transpose in**: a block of the user's ``(samples, dof)`` states (flat, C-ordered: they go in
   unchanged) into per-link rows of :data:`LANES` samples, ``W[(j * ROWS + r) * LANES + s]``: a whole
   block in tiles of 8 samples x 8 columns through SIMD registers, a partial block one row of ``W`` at
   a time (:func:`exo_bench.models.machine.simd_blocks.block_transposes`). exo5-3d, 10,000 samples, one
   thread, the whole kernel: 44.3 ns per sample against 51.7 with the loops alone (whose column
   reads LLVM makes gathers), the quiet machine, one run each;
2. **per link j**: ``sin``/``cos`` of its angles in branch-free arithmetic
   (:func:`exo_bench.models.machine.fast_trig.sincos_reduced`; the angles beyond its range, and NaN, are
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

The physics is the element functions the other kernels call; this file only arranges the loops,
once for both dimensions (:func:`build`: ``dim`` and the element steps are constants of its
closures), step 2 with ``newton-euler``'s kernel (:mod:`exo_bench.models.machine.simd_blocks`).
The rows of one link sit at constant distances (multiples of :data:`LANES`) in one scratch array,
so LLVM proves that a loop's stores do not overlap its loads without being told (no ``prange``
needed for the no-aliasing knowledge); steps 3 and 4 read one scratch array and write another,
which LLVM checks once per loop at run time. Unit stride everywhere but in the two transposes.

Against the per-sample kernel the result differs only by the ``sin``/``cos`` (at most :data:`~exo_bench.models.machine.fast_trig.ULPS` ulp
each, :mod:`exo_bench.models.machine.fast_trig`): the same operations in the same order otherwise.

**Threads.** :func:`run` splits a batch of at least :data:`exo_bench.models.machine.simd_blocks.PARALLEL_MIN_ELEMENTS` state elements
(samples x dof) over ``numba.get_num_threads()`` threads (the caller's and a pool's), which pull shares of it and
call the serial kernel on each (it releases the GIL): numba's threading layer is never entered, so the batch path runs
at the same speed whichever layer numba picked or the user started first (OpenMP's spinning
threads cost 7-8 ms per call of a ``prange`` kernel after a user's code started them).

numba's on-disk cache of these kernels is keyed on their folder, the files of the functions they
inline (the element functions) and the shared ``simd_blocks.py``, ``fast_trig.py``, ``simd_blocks.py``
and ``numba_runtime.py`` (:mod:`exo_bench.models.machine.numba_cache`): an edit to any of them recompiles them.
"""

from __future__ import annotations

from types import SimpleNamespace

from numba import njit
from numba.extending import register_jitable

from exo_bench.matrix_method.closed_forms.factored import forces_2d, forces_3d, kappa_2d, kappa_3d
from exo_bench.models.machine.numba_runtime import JIT
from exo_bench.models.machine import simd_blocks
from exo_bench.models.machine.simd_blocks import states_2d, states_3d
from exo_bench.models.machine.simd_blocks import (
    CF,
    CP,
    F0,
    F1,
    F2,
    FROWS,
    K0,
    K1,
    K2,
    LANES,
    LEN,
    LEN2,
    O0,
    O1,
    O2,
    ROWS,
    SF,
    SP,
)
from exo_bench.models.machine.simd_blocks import _block_rows_in, _block_rows_out, _block_scratch


@register_jitable
def _kappa_3d(W, at, B, x, cf, sf, cp, sp):
    """2. ``kappa_j`` of sample ``at`` of a spatial link (the ``link`` of :func:`exo_bench.models.machine.simd_blocks.link_pass`)."""
    l, w, v, ld, wdd, vdd, ldd = states_3d(W, at, B)
    W[at + K0 * B], W[at + K1 * B], W[at + K2 * B] = kappa_3d(l, w, v, ld, wdd, vdd, ldd, cf, sf, cp, sp)


@register_jitable
def _kappa_2d(W, at, B, x, cf, sf, cp, sp):
    """2. ``kappa_j`` of sample ``at`` of a planar link (phi in row 0, l in row 1)."""
    l, w, ld, wdd, ldd = states_2d(W, at, B)
    W[at + K0 * B], W[at + K1 * B] = kappa_2d(l, w, ld, wdd, ldd, cf, sf)


@register_jitable
def _forces_3d(W, F, at, f, B, gnu):
    """4. The forces of sample ``at`` of a spatial link (its rows of ``F`` at ``f``) from its ``f_i``."""
    cf, sf, cp, sp, l = W[at + CF * B], W[at + SF * B], W[at + CP * B], W[at + SP * B], W[at + LEN * B]
    F[f + O0 * B], F[f + O1 * B], F[f + O2 * B] = forces_3d(
        l, cf, sf, cp, sp, F[f + F0 * B], F[f + F1 * B], F[f + F2 * B], gnu
    )


@register_jitable
def _forces_2d(W, F, at, f, B, gnu):
    """4. The forces ``M_phi, F`` (rows ``O0, O1``) of sample ``at`` of a planar link."""
    cf, sf, l = W[at + CF * B], W[at + SF * B], W[at + LEN2 * B]
    F[f + O0 * B], F[f + O1 * B] = forces_2d(l, cf, sf, F[f + F0 * B], F[f + F1 * B], gnu)


def _jit(dim: int):
    """``njit(**JIT)`` under a qualified name that carries ``dim`` (``build.<locals>.simd`` becomes
    ``..._3d``): two closures that share a symbol in numba's cache then have the same code
    (:func:`exo_bench.models.machine.numba_runtime.jit_for` says why)."""

    def decorate(fn):
        fn.__qualname__ = f"{fn.__qualname__}_{dim}d"
        return njit(**JIT)(fn)

    return decorate


def build(dim: int) -> SimpleNamespace:
    """The kernel for ``dim`` (2 or 3), one source for both: ``compute`` (steps 2-4) and the driver
    ``simd`` (1-4 block by block). ``dim`` and the element steps are constants of the closures: numba
    compiles each dimension's loops as if written out for it (the branches on ``dim`` fold away)."""
    kappa, forces = (_kappa_3d, _forces_3d) if dim == 3 else (_kappa_2d, _forces_2d)
    link_pass, libm_pass = simd_blocks.link_pass, simd_blocks.libm_pass

    @_jit(dim)
    def compute(p, m, W, F):
        """2-4. From the rows of ``W`` (``m`` samples) to the forces in ``F``."""
        n = p.shape[0]
        B = LANES
        outside = 0
        for j in range(n):  # 2. sin, cos, kappa_j
            outside += link_pass(W, j * ROWS * B, m, B, dim, kappa, 1.0)
        if outside:  #    libm for the angles beyond RANGE (and NaN)
            for j in range(n):
                libm_pass(W, j * ROWS * B, m, B, dim, kappa, 1.0)
        for i in range(n):  # 3. f_i = sum_j c_ij kappa_j
            f = i * FROWS * B
            for s in range(m):
                F[f + F0 * B + s], F[f + F1 * B + s] = 0.0, 0.0
                if dim == 3:
                    F[f + F2 * B + s] = 0.0
            for j in range(n):
                c, w = p[i, j], j * ROWS * B
                for s in range(m):
                    F[f + F0 * B + s] += c * W[w + K0 * B + s]
                    F[f + F1 * B + s] += c * W[w + K1 * B + s]
                    if dim == 3:
                        F[f + F2 * B + s] += c * W[w + K2 * B + s]
        for i in range(n):  # 4. the forces of link i
            f, w, gnu = i * FROWS * B, i * ROWS * B, p[i, n + 1] * p[i, n]
            for s in range(m):
                forces(W, F, w + s, f + s, B, gnu)

    @_jit(dim)
    def simd(p, q, qd, qdd, o, start, stop, S=None):
        """Samples ``start .. stop - 1`` of the flat ``(samples, dof)`` states into ``o``, :data:`LANES`
        at a time; ``S``: the scratch of ``_block_scratch(n, dim)`` (kept per thread,
        :class:`exo_bench.models.machine.simd_blocks.ThreadScratch`), or None to allocate it here."""
        n = p.shape[0]
        if S is None:
            W, F, T = _block_scratch(n, dim)
        else:
            W, F, T = S
        for s0 in range(start, stop, LANES):
            if stop - s0 >= LANES:  # a whole block: the trip counts are the constant LANES (module docstring)
                _block_rows_in(q, qd, qdd, s0, LANES, n, dim, W, T)
                compute(p, LANES, W, F)
                _block_rows_out(o, s0, LANES, n, dim, F, T)
            else:
                m = stop - s0
                _block_rows_in(q, qd, qdd, s0, m, n, dim, W, T)
                compute(p, m, W, F)
                _block_rows_out(o, s0, m, n, dim, F, T)

    return SimpleNamespace(compute=compute, simd=simd)


_2D, _3D = build(2), build(3)
_compute_2d, _compute_3d = _2D.compute, _3D.compute
simd_2d, simd_3d = _2D.simd, _3D.simd

#: dim -> the kernel ``(params, q, qd, qdd, o, start, stop[, S])`` on flat states
KERNELS = {2: simd_2d, 3: simd_3d}
#: ``scratch(n, blocks) -> (W, F, T)``: the kernels' scratch, the ``S`` they take
scratch = _block_scratch
