"""Blocks of samples, samples innermost: the layout shared by the kernels that vectorise across samples.

A kernel of this kind (:mod:`exo_bench.matrix_method.numba_kernels.simd` for ``matrix-factored``,
:mod:`exo_bench.models.newton_euler.simd` for ``newton-euler``) takes :data:`LANES` samples of the
user's flat, C-ordered ``(samples, dof)`` states at a time, transposes them into per-link rows of
:data:`LANES` samples (:func:`_rows_in`), runs each step as a loop over the samples that LLVM turns
into SIMD instructions, and transposes the results back (:func:`_rows_out`). :func:`run` splits a
large batch over threads without entering numba's threading layer.

Scratch layout: per link ``j`` :data:`ROWS` rows of ``W`` (the states of block ``k``: rows ``k``,
``3 + k``, ``6 + k`` for ``q, qd, qdd``; then cos and sin of phi and psi, and ``kappa``) and
:data:`FROWS` rows of ``F`` (three of sums, then the results, read by :func:`_rows_out`).

Kept in the lowest layer (``models``) so that both families share it (moved here from the matrix
family's simd.py, which imports it).
"""

from __future__ import annotations

import threading
import time

import numba
import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from exo_bench.models.numba_runtime import JIT, RUNTIME, ensure, jit_for
from exo_bench.models.simd_tiles import TILE, tile_in, tile_out

ensure()  # numba's runtime set-up (models/numba_runtime.py), before the kernels below are defined
_jit = njit(**JIT)


def _prefetcher(write: int):
    @intrinsic
    def prefetch(typingctx, arr, idx):
        sig = types.void(arr, idx)

        def codegen(context, builder, signature, args):
            ary = context.make_array(signature.args[0])(context, builder, args[0])
            ptr = builder.gep(ary.data, [args[1]])
            i32 = ir.IntType(32)
            fn = cgutils.get_or_insert_function(
                builder.module, ir.FunctionType(ir.VoidType(), [ptr.type, i32, i32, i32]), "llvm.prefetch.p0"
            )
            builder.call(fn, [ptr, ir.Constant(i32, write), ir.Constant(i32, 3), ir.Constant(i32, 1)])
            return context.get_dummy_value()

        return sig, codegen

    return prefetch


#: ``prefetch(arr, idx)``: ask for the cache line of ``arr[idx]`` (LLVM's ``llvm.prefetch``, kept in
#: every level), to read or to write. No bounds check: a prefetch never faults.
prefetch_read, prefetch_write = _prefetcher(0), _prefetcher(1)

#: doubles per cache line
LINE = 8


@_jit
def prefetch_share(q, qd, qdd, o, lo, hi, share, shares):
    """Prefetch share ``share`` of ``shares`` of the cache lines of the flat elements ``lo .. hi - 1`` of
    the states (to read) and of the result (to write): a kernel calls it once per link with the next
    block's elements, so the lines arrive while this block computes, a few per link."""
    per = -(-(hi - lo) // (shares * LINE)) * LINE
    a = lo + share * per
    b = min(hi, a + per)
    for i in range(a, b, LINE):
        prefetch_read(q, i)
        prefetch_read(qd, i)
        prefetch_read(qdd, i)
        prefetch_write(o, i)


#: Samples computed at once (a multiple of every SIMD width: 2, 4, 8 doubles).
LANES = 32

# Rows of one link in the scratch W (row numbers of the states: block k of q, qd, qdd in rows k,
# 3 + k, 6 + k; then cos and sin of phi and psi, kappa) and in the scratch F (f, then the forces).
PHI, PSI, LEN, W1, V1, L1, W2, V2, L2, CF, SF, CP, SP, K0, K1, K2 = range(16)
LEN2, L1_2, L2_2 = 1, 4, 7  # planar: l, l', l'' (block 1 of q, qd, qdd)
ROWS = 16
F0, F1, F2, O0, O1, O2 = range(6)
FROWS = 6
# Index arithmetic on unsigned integers (U) in the scalar transposes: numba wraps negative signed
# indices around (a compare and a select per access), which these loops cannot need.
U = np.uintp


@_jit
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


@_jit
def _rows_out(o, s0, m, n, blocks, F):
    """5. The forces of ``F`` into samples ``s0 .. s0 + m - 1`` of the flat ``(samples, dof)`` ``o``."""
    dof = blocks * n
    B = LANES
    for s in range(m):
        b = (s0 + s) * dof
        for k in range(blocks):
            for i in range(n):
                o[U(b + k * n + i)] = F[U((i * FROWS + O0 + k) * B + s)]


def by_link_transposes(lanes: int):
    """The two by-link transposes (:func:`_rows_in_by_link`, :func:`_rows_out_by_link`) compiled for
    blocks of ``lanes`` samples (numba freezes ``lanes`` as a constant, as it does :data:`LANES`)."""
    B = lanes

    @jit_for(lanes)
    def _rows_in_by_link(q, qd, qdd, s0, m, n, blocks, W):
        """:func:`_rows_in` in the other loop order: per state ``(block k, link j)``, the ``m`` samples in
        turn, so that the stores run along a row of ``W`` and the loads along a column of the states
        (stride ``dof``). :func:`_rows_in` stores ``W`` at a stride of ``ROWS * LANES`` doubles (4 KiB,
        one cache set) and rereads each sample's row ``n`` times further apart as ``n`` grows: 3D
        chains of n = 100 and 1000 took 21.5 and 28.6 ns per link and sample for both transposes, this
        order 17.7 and 16.0 (n = 5: 6.2 and 4.9; the shared 2-core machine, load 2.9)."""
        dof = blocks * n
        for k in range(blocks):
            for j in range(n):
                w = (j * ROWS + k) * B
                c = s0 * dof + k * n + j
                for s in range(m):
                    W[U(w + s)] = q[U(c + s * dof)]
                    W[U(w + 3 * B + s)] = qd[U(c + s * dof)]
                    W[U(w + 6 * B + s)] = qdd[U(c + s * dof)]

    @jit_for(lanes)
    def _rows_out_by_link(o, s0, m, n, blocks, F):
        """:func:`_rows_out` in the loop order of :func:`_rows_in_by_link`: the loads along a row of ``F``."""
        dof = blocks * n
        for k in range(blocks):
            for i in range(n):
                f = (i * FROWS + O0 + k) * B
                c = s0 * dof + k * n + i
                for s in range(m):
                    o[U(c + s * dof)] = F[U(f + s)]

    return _rows_in_by_link, _rows_out_by_link


_rows_in_by_link, _rows_out_by_link = by_link_transposes(LANES)

#: Spare rows of ``W`` (in units of a block) past the links' rows: the masked columns of a
#: block's last tile of states land there (:func:`block_transposes`).
SPARE = 7


def block_transposes(lanes: int):
    """The scratch and the two transposes of a kernel with blocks of ``lanes`` samples (a multiple of
    :data:`~exo_bench.models.simd_tiles.TILE`): ``scratch(n, blocks) -> W, F, T``, ``rows_in(q, qd,
    qdd, s0, m, n, blocks, W, T)`` and ``rows_out(o, s0, m, n, blocks, F, T)``.

    A whole block (``m == lanes``, a constant where the kernel inlines them) moves in tiles of 8
    samples x 8 columns through SIMD registers (:mod:`exo_bench.models.simd_tiles`); a partial block
    by the loops of :func:`by_link_transposes`. ``T`` holds the tiles' destinations: for column ``c``
    of the states (``c = k n + j``: block ``k`` of link ``j``) its row of ``W`` and, from ``P`` on (the
    columns rounded up to tiles), its row of results in ``F``; the columns past ``dof`` go to the
    :data:`SPARE` rows of ``W`` and read row 0 of ``F`` (masked out).

    Both transposes of whole blocks against the loops alone (whose column reads LLVM makes
    ``vgatherqpd``), 3D, one thread, best of 9 interleaved, the quiet machine: exo5-3d, 10,000
    samples, 13.5 against 22.0 ns per sample; n = 1000, 128 samples, 4.75 against 8.0 ns per link
    and sample; n = 100, 1024 samples (9.8 MB, beyond L2), 4.8 against 4.7: there both stream from
    L3 at the same rate."""
    B = lanes
    assert B % TILE == 0, "blocks of whole tiles"
    by_link_in, by_link_out = by_link_transposes(lanes)

    @jit_for(lanes)
    def scratch(n, blocks):
        dof = blocks * n
        P = -(-dof // TILE) * TILE
        T = np.empty(2 * P, dtype=np.int64)
        for c in range(P):
            if c < dof:
                k, j = c // n, c % n
                T[c], T[P + c] = (j * ROWS + k) * B, (j * FROWS + O0 + k) * B
            else:
                T[c], T[P + c] = n * ROWS * B, 0
        return np.empty((n * ROWS + SPARE) * B), np.empty(n * FROWS * B), T

    @jit_for(lanes)
    def rows_in(q, qd, qdd, s0, m, n, blocks, W, T):
        """1. Samples ``s0 .. s0 + m - 1`` into the rows of ``W`` (:func:`_rows_in`'s layout)."""
        if m == B:
            dof = blocks * n
            for r0 in range(0, B, TILE):
                base = (s0 + r0) * dof
                for c0 in range(0, dof, TILE):
                    tile_in(q, base + c0, dof, dof - c0, W, T, c0, r0)
                    tile_in(qd, base + c0, dof, dof - c0, W, T, c0, r0 + 3 * B)
                    tile_in(qdd, base + c0, dof, dof - c0, W, T, c0, r0 + 6 * B)
        else:
            by_link_in(q, qd, qdd, s0, m, n, blocks, W)

    @jit_for(lanes)
    def rows_out(o, s0, m, n, blocks, F, T):
        """5. The forces of ``F`` into samples ``s0 .. s0 + m - 1`` of ``o``."""
        if m == B:
            dof = blocks * n
            P = T.shape[0] // 2
            for r0 in range(0, B, TILE):
                base = (s0 + r0) * dof
                for c0 in range(0, dof, TILE):
                    tile_out(F, T, P + c0, r0, o, base + c0, dof, dof - c0)
        else:
            by_link_out(o, s0, m, n, blocks, F)

    return scratch, rows_in, rows_out


_block_scratch, _block_rows_in, _block_rows_out = block_transposes(LANES)

#: Shares per thread of a split batch: the threads pull shares until none is left.
SHARES_PER_THREAD = 8

#: A batch of at least this many state elements (samples x dof) is split over threads by
#: :func:`run`: the split costs 50-70 us per call here (a pool thread woken, the GIL passed at each
#: share), so it pays from a few hundred us of work on. Two threads against one, the quiet 2-core
#: machine, median of 15 interleaved: exo5-3d (15 dof) 4096 samples 1.44x the time, 8192 0.94x,
#: 16,384 0.78x; 3D chain of 100, newton-euler, 128 samples (38,400 elements) 1.10x, 256 0.79x;
#: chain of 1000, 32 samples 1.04x, 64 0.75x. A threshold in samples (4096, numba's parallel
#: drivers') kept a 3D chain of 1000 (3000 dof, 15 us per sample) on one thread up to 4096 samples.
PARALLEL_MIN_ELEMENTS = 2**17


def parallel_min_samples(dof: int) -> int:
    """The fewest samples of ``dof`` coordinates that :func:`run` splits over threads."""
    return max(1, -(-PARALLEL_MIN_ELEMENTS // max(dof, 1)))


class ThreadScratch:
    """Each thread's scratch ``(W, F, T)`` of one kernel for one mechanism, made by the kernel's
    ``scratch(n, blocks)`` at the thread's first call and reused by its later ones (Pinocchio's model
    and data: prepare once, no allocation in the hot path).

    A kernel called without it allocates its scratch at each call, and :func:`run` calls it once per
    share: newton-euler on a 3D chain of 1000 took 3.6 MB per share, 15 shares per batch of 1398
    samples. Where the C library maps each such block afresh, the OS zeroes its pages on every call:
    under ``MALLOC_TRIM_THRESHOLD_=65536`` (which Dask's nanny sets for its workers, and which turns
    off glibc's dynamic mmap threshold) that batch took 10.6-11.3 us per sample against 8.3-8.5
    without (two threads, the quiet machine). The memory is kept while the model lives: one scratch
    per thread that ran the model (3.6 MB each at n = 1000, blocks of 16)."""

    def __init__(self, make, n: int, blocks: int):
        self._make, self._n, self._blocks = make, n, blocks
        self._local = threading.local()

    def __call__(self) -> tuple:
        s = getattr(self._local, "scratch", None)
        if s is None:
            s = self._local.scratch = self._make(self._n, self._blocks)
        return s


#: The calling thread waits for the pool's last shares at most this many times the longest share it
#: computed itself (the same kernel on a share of the same size: the predicted cost of one share) ...
WAIT_ALLOWANCE = 1000.0
#: ... and at least this many seconds (a pool thread the OS keeps off its core on a loaded machine).
WAIT_FLOOR = 120.0


def run(
    kernel,
    params,
    q,
    qd,
    qdd,
    o,
    samples: int,
    threads: int | None = None,
    scratch: ThreadScratch | None = None,
    wait_limit: float | None = None,
) -> None:
    """``kernel`` over a batch of flat states into ``o``: in the calling thread, or for at least
    :data:`PARALLEL_MIN_ELEMENTS` state elements (:func:`parallel_min_samples`) over ``threads`` (default
    ``numba.get_num_threads()``) threads: the calling thread and ``threads - 1`` of a pool pull
    shares of whole blocks (:data:`SHARES_PER_THREAD` per thread) until none is left, each share
    computed by one thread (the kernel releases the GIL). The calling thread waits only for shares
    already started: a pool thread that the OS has not scheduled yet finds nothing left and costs
    nothing. A pool thread that the OS takes off its core in the middle of a share is waited for,
    though: on the 2-core machine shared by several jobs (load average 7) the 2-thread split of
    10,000 exo5-3d samples took 0.1-0.7 us per sample against 0.09 on one thread; on a quiet
    machine it is the two cores' speed. ``numba.set_num_threads(1)`` keeps a batch on the calling
    thread. ``scratch``: each thread passes its own scratch to the kernel (:class:`ThreadScratch`);
    without it the kernel allocates its scratch at each call. The wait for the pool's shares is bounded:
    ``wait_limit`` seconds (default: :data:`WAIT_ALLOWANCE` times the calling thread's longest share, at
    least :data:`WAIT_FLOOR`); beyond it no further share starts and a TimeoutError names the batch and
    the limit (``o`` is then incomplete, as after any error of the kernel)."""
    small = samples == 0 or q.shape[0] < PARALLEL_MIN_ELEMENTS  # parallel_min_samples, inline (issue 47)
    if threads is None:
        threads = 1 if small else numba.get_num_threads()
    if threads <= 1 or small:
        if scratch is None:
            kernel(params, q, qd, qdd, o, 0, samples)
        else:  # ThreadScratch's own, without its call where this thread has it
            kernel(params, q, qd, qdd, o, 0, samples, getattr(scratch._local, "scratch", None) or scratch())
        return
    size = -(-samples // (threads * SHARES_PER_THREAD * LANES)) * LANES
    starts = iter(range(0, samples, size))
    cond = threading.Condition()
    busy = [0]
    errors = []
    longest = [0.0]  # the calling thread's longest share, seconds

    def work(timed: bool = False):
        mine = () if scratch is None else (getattr(scratch._local, "scratch", None) or scratch(),)
        while True:
            with cond:
                s0 = next(starts, None)
                if s0 is None:
                    return
                busy[0] += 1
            try:
                t0 = time.perf_counter() if timed else 0.0
                kernel(params, q, qd, qdd, o, s0, min(samples, s0 + size), *mine)
                if timed:
                    longest[0] = max(longest[0], time.perf_counter() - t0)
            except BaseException as e:  # noqa: BLE001 - re-raised in the calling thread
                errors.append(e)
            finally:
                with cond:
                    busy[0] -= 1
                    cond.notify_all()

    pool = RUNTIME.pool(threads - 1)  # numba_runtime holds the one pool
    for _ in range(threads - 1):
        pool.submit(work)
    work(timed=True)
    limit = max(WAIT_FLOOR, WAIT_ALLOWANCE * longest[0]) if wait_limit is None else float(wait_limit)
    with cond:
        if not cond.wait_for(lambda: not busy[0], timeout=limit):
            starts = iter(())  # no share starts after this (work() reads this variable of run)
            raise TimeoutError(
                f"SIMD batch of {samples} samples on {threads} threads: {busy[0]} share(s) of {size} samples "
                f"still running after the limit of {limit:g} s (the calling thread's longest share took "
                f"{longest[0]:.3g} s)"
            )
    if errors:
        raise errors[0]
