"""Method ``matrix-factored``, compiled to vectorise across samples: the batched path.

The per-sample kernel (:mod:`matrix_method.compiled_factored`) computes each sample whole, with
libm's ``sin`` and ``cos`` per angle: nothing is vectorised. This kernel computes :data:`LANES`
samples at once, each step a loop over the samples that LLVM turns into SIMD instructions:

1. **transpose in**: a block of the user's ``(samples, dof)`` states (flat, C-ordered: they go in
   unchanged) into per-link rows of :data:`LANES` samples, ``W[(j * ROWS + r) * LANES + s]``;
2. **per link j**: ``sin``/``cos`` of its angles in branch-free arithmetic
   (:func:`matrix_method.fast_trig.sincos_reduced`; the angles beyond its range, and NaN, are
   redone with libm by a scalar loop that only they enter) and ``kappa_j``
   (:func:`matrix_method.factored_terms.kappa_3d`);
3. ``f_i = sum_j c_ij kappa_j``: one multiply-add per sample per (i, j, axis), summed in the same
   order as the per-sample kernel;
4. **per link i**: the forces (:func:`matrix_method.factored_terms.forces_3d`), then **transpose
   out** into the user's ``(samples, dof)`` result.

A ``(dof, samples)`` entry (copying rows of the caller's arrays instead of transposing) was tried
and measured 3x slower here: a block then reads 45 rows of exo5-3d at once (and writes 15), more
streams than the hardware prefetchers follow, each row on its own page.

The physics is the element functions the other kernels call; this file only arranges the loops.
The rows of one link sit at constant distances (multiples of :data:`LANES`) in one scratch array,
so LLVM proves that a loop's stores do not overlap its loads without being told (no ``prange``
needed for the no-aliasing knowledge); steps 3 and 4 read one scratch array and write another,
which LLVM checks once per loop at run time. Unit stride everywhere but in the two transposes.

Against the per-sample kernel the result differs only by the ``sin``/``cos`` (at most one ulp
each, :mod:`matrix_method.fast_trig`): the same operations in the same order otherwise.

**Threads.** :func:`run` splits a batch of at least :data:`compiled.PARALLEL_MIN_SAMPLES` samples
over ``numba.get_num_threads()`` threads (the caller's and a pool's), which pull shares of it and
call the serial kernel on each (it releases the GIL): numba's threading layer is never entered, so the batch path runs
at the same speed whichever layer numba picked or the user started first (OpenMP's spinning
threads cost 7-8 ms per call of a ``prange`` kernel after a user's code started them).

numba's on-disk cache is keyed on this file: after editing :mod:`factored_terms` or
:mod:`fast_trig`, delete ``matrix_method/__pycache__/compiled_simd*.nb?`` (the tests would
catch the stale kernel).
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from exo_bench.matrix_method.compiled import JIT, PARALLEL_MIN_SAMPLES, njit
from exo_bench.matrix_method.factored_terms import forces_2d, forces_3d, kappa_2d, kappa_3d
from exo_bench.matrix_method.fast_trig import RANGE, sincos_reduced

#: Samples computed at once (a multiple of every SIMD width: 2, 4, 8 doubles).
LANES = 32

# Rows of one link in the scratch W (row numbers of the states: block k of q, qd, qdd in rows k,
# 3 + k, 6 + k; then cos and sin of phi and psi, kappa) and in the scratch F (f, then the forces).
PHI, PSI, LEN, W1, V1, L1, W2, V2, L2, CF, SF, CP, SP, K0, K1, K2 = range(16)
LEN2, L1_2, L2_2 = 1, 4, 7          # planar: l, l', l'' (block 1 of q, qd, qdd)
ROWS = 16
F0, F1, F2, O0, O1, O2 = range(6)
FROWS = 6
# Index arithmetic on unsigned integers (U) in the scalar transposes: numba wraps negative signed
# indices around (a compare and a select per access), which these loops cannot need.
U = np.uintp


@njit(**JIT)
def _rows_in(q, qd, qdd, s0, m, n, blocks, W):
    """1. Samples ``s0 .. s0 + m - 1`` of flat ``(samples, blocks * n)`` states into the per-link rows
    of ``W`` (block ``k`` of link ``j``: rows ``k``, ``3 + k``, ``6 + k`` for ``q, qd, qdd``)."""
    dof = blocks * n
    B = LANES
    for s in range(m):
        b = (s0 + s) * dof
        for k in range(blocks):
            for j in range(n):
                w = (j * ROWS + k) * B + s
                W[U(w)] = q[U(b + k * n + j)]
                W[U(w + 3 * B)] = qd[U(b + k * n + j)]
                W[U(w + 6 * B)] = qdd[U(b + k * n + j)]


@njit(**JIT)
def _rows_out(o, s0, m, n, blocks, F):
    """5. The forces of ``F`` into samples ``s0 .. s0 + m - 1`` of the flat ``(samples, dof)`` ``o``."""
    dof = blocks * n
    B = LANES
    for s in range(m):
        b = (s0 + s) * dof
        for k in range(blocks):
            for i in range(n):
                o[U(b + k * n + i)] = F[U((i * FROWS + O0 + k) * B + s)]


@njit(**JIT)
def _compute_3d(p, m, W, F):
    """2-4. From the rows of ``W`` (``m`` samples) to the forces in ``F``, spatial."""
    n = p.shape[0]
    B = LANES
    outside = 0
    for j in range(n):                                   # 2. sin, cos, kappa_j
        w = j * ROWS * B
        for s in range(m):
            phi, psi = W[w + PHI * B + s], W[w + PSI * B + s]
            okf, okp = abs(phi) <= RANGE, abs(psi) <= RANGE
            sf, cf = sincos_reduced(phi if okf else 0.0)
            sp, cp = sincos_reduced(psi if okp else 0.0)
            outside += (0 if okf else 1) + (0 if okp else 1)
            W[w + CF * B + s], W[w + SF * B + s], W[w + CP * B + s], W[w + SP * B + s] = cf, sf, cp, sp
            W[w + K0 * B + s], W[w + K1 * B + s], W[w + K2 * B + s] = kappa_3d(
                W[w + LEN * B + s], W[w + W1 * B + s], W[w + V1 * B + s], W[w + L1 * B + s],
                W[w + W2 * B + s], W[w + V2 * B + s], W[w + L2 * B + s], cf, sf, cp, sp)
    if outside:                                          #    libm for the angles beyond RANGE (and NaN)
        for j in range(n):
            w = j * ROWS * B
            for s in range(m):
                phi, psi = W[w + PHI * B + s], W[w + PSI * B + s]
                if not (abs(phi) <= RANGE and abs(psi) <= RANGE):
                    cf, sf, cp, sp = math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi)
                    W[w + CF * B + s], W[w + SF * B + s], W[w + CP * B + s], W[w + SP * B + s] = cf, sf, cp, sp
                    W[w + K0 * B + s], W[w + K1 * B + s], W[w + K2 * B + s] = kappa_3d(
                        W[w + LEN * B + s], W[w + W1 * B + s], W[w + V1 * B + s], W[w + L1 * B + s],
                        W[w + W2 * B + s], W[w + V2 * B + s], W[w + L2 * B + s], cf, sf, cp, sp)
    for i in range(n):                                   # 3. f_i = sum_j c_ij kappa_j
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
    for i in range(n):                                   # 4. the forces of link i
        f, w, gnu = i * FROWS * B, i * ROWS * B, p[i, n + 1] * p[i, n]
        for s in range(m):
            F[f + O0 * B + s], F[f + O1 * B + s], F[f + O2 * B + s] = forces_3d(
                W[w + LEN * B + s], W[w + CF * B + s], W[w + SF * B + s], W[w + CP * B + s], W[w + SP * B + s],
                F[f + F0 * B + s], F[f + F1 * B + s], F[f + F2 * B + s], gnu)


@njit(**JIT)
def _compute_2d(p, m, W, F):
    """2-4. From the rows of ``W`` (``m`` samples) to the forces in ``F``, planar (the rows of the
    planar blocks: phi in row 0, l in row 1; the forces ``M_phi, F`` in ``O0, O1``)."""
    n = p.shape[0]
    B = LANES
    outside = 0
    for j in range(n):                                   # 2. sin, cos, kappa_j
        w = j * ROWS * B
        for s in range(m):
            phi = W[w + PHI * B + s]
            okf = abs(phi) <= RANGE
            sf, cf = sincos_reduced(phi if okf else 0.0)
            outside += 0 if okf else 1
            W[w + CF * B + s], W[w + SF * B + s] = cf, sf
            W[w + K0 * B + s], W[w + K1 * B + s] = kappa_2d(
                W[w + LEN2 * B + s], W[w + W1 * B + s], W[w + L1_2 * B + s], W[w + W2 * B + s],
                W[w + L2_2 * B + s], cf, sf)
    if outside:                                          #    libm for the angles beyond RANGE (and NaN)
        for j in range(n):
            w = j * ROWS * B
            for s in range(m):
                phi = W[w + PHI * B + s]
                if not abs(phi) <= RANGE:
                    cf, sf = math.cos(phi), math.sin(phi)
                    W[w + CF * B + s], W[w + SF * B + s] = cf, sf
                    W[w + K0 * B + s], W[w + K1 * B + s] = kappa_2d(
                        W[w + LEN2 * B + s], W[w + W1 * B + s], W[w + L1_2 * B + s], W[w + W2 * B + s],
                        W[w + L2_2 * B + s], cf, sf)
    for i in range(n):                                   # 3. f_i = sum_j c_ij kappa_j
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
    for i in range(n):                                   # 4. the forces of link i
        f, w, gnu = i * FROWS * B, i * ROWS * B, p[i, n + 1] * p[i, n]
        for s in range(m):
            F[f + O0 * B + s], F[f + O1 * B + s] = forces_2d(
                W[w + LEN2 * B + s], W[w + CF * B + s], W[w + SF * B + s], F[f + F0 * B + s], F[f + F1 * B + s], gnu)


@njit(**JIT)
def _scratch(n):
    return np.empty(n * ROWS * LANES), np.empty(n * FROWS * LANES)


@njit(**JIT)
def simd_3d(p, q, qd, qdd, o, start, stop):
    """Samples ``start .. stop - 1`` of the flat spatial ``(samples, dof)`` states into ``o``,
    :data:`LANES` at a time."""
    n = p.shape[0]
    W, F = _scratch(n)
    for s0 in range(start, stop, LANES):
        m = min(LANES, stop - s0)
        _rows_in(q, qd, qdd, s0, m, n, 3, W)
        _compute_3d(p, m, W, F)
        _rows_out(o, s0, m, n, 3, F)


@njit(**JIT)
def simd_2d(p, q, qd, qdd, o, start, stop):
    """Samples ``start .. stop - 1`` of the flat planar ``(samples, dof)`` states into ``o``,
    :data:`LANES` at a time."""
    n = p.shape[0]
    W, F = _scratch(n)
    for s0 in range(start, stop, LANES):
        m = min(LANES, stop - s0)
        _rows_in(q, qd, qdd, s0, m, n, 2, W)
        _compute_2d(p, m, W, F)
        _rows_out(o, s0, m, n, 2, F)


#: dim -> the kernel ``(params, q, qd, qdd, o, start, stop)`` on flat states
KERNELS = {2: simd_2d, 3: simd_3d}

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _pool(workers: int) -> ThreadPoolExecutor:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None or _POOL._max_workers < workers:
            _POOL = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="exo-bench-simd")
        return _POOL


#: Shares per thread of a split batch: the threads pull shares until none is left.
SHARES_PER_THREAD = 8


def run(kernel, params, q, qd, qdd, o, samples: int, threads: int | None = None) -> None:
    """``kernel`` over a batch of flat states into ``o``: in the calling thread, or for at least
    :data:`compiled.PARALLEL_MIN_SAMPLES` samples over ``threads`` (default
    ``numba.get_num_threads()``) threads: the calling thread and ``threads - 1`` of a pool pull
    shares of whole blocks (:data:`SHARES_PER_THREAD` per thread) until none is left, each share
    computed by one thread (the kernel releases the GIL). The calling thread waits only for shares
    already started: a pool thread that the OS has not scheduled yet finds nothing left and costs
    nothing. A pool thread that the OS takes off its core in the middle of a share is waited for,
    though: on the 2-core machine shared by several jobs (load average 7) the 2-thread split of
    10,000 exo5-3d samples took 0.1-0.7 us per sample against 0.09 on one thread; on a quiet
    machine it is the two cores' speed. ``numba.set_num_threads(1)`` keeps a batch on the calling
    thread."""
    if threads is None:
        threads = numba.get_num_threads() if samples >= PARALLEL_MIN_SAMPLES else 1
    if threads <= 1 or samples < PARALLEL_MIN_SAMPLES:
        kernel(params, q, qd, qdd, o, 0, samples)
        return
    size = -(-samples // (threads * SHARES_PER_THREAD * LANES)) * LANES
    starts = iter(range(0, samples, size))
    cond = threading.Condition()
    busy = [0]
    errors = []

    def work():
        while True:
            with cond:
                s0 = next(starts, None)
                if s0 is None:
                    return
                busy[0] += 1
            try:
                kernel(params, q, qd, qdd, o, s0, min(samples, s0 + size))
            except BaseException as e:  # noqa: BLE001 - re-raised in the calling thread
                errors.append(e)
            finally:
                with cond:
                    busy[0] -= 1
                    cond.notify_all()

    pool = _pool(threads - 1)
    for _ in range(threads - 1):
        pool.submit(work)
    work()
    with cond:
        while busy[0]:
            cond.wait()
    if errors:
        raise errors[0]

