"""Blocks of samples, samples innermost: the layout, the moves in and out (8 x 8 tiles) and the per-link
angle step shared by the kernels that vectorise across samples: one concept, the SIMD plumbing.

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

**The tiles.** 8 x 8 transposes of doubles in SIMD registers, as numba intrinsics (LLVM IR written here).

The kernels that vectorise across samples move each block of
the user's ``(samples, dof)`` states into per-link rows of samples and the results back. Written as
loops over the samples, the move in reads a column of the states (stride ``dof``): LLVM makes it a
``vgatherqpd`` per 8 samples, which Zen 4 runs at several cycles each, and the move out stores one
double at a time. Here 8 samples x 8 columns move as 8 vector loads, 24 shuffles (the classic
three-stage network: pairs of doubles, pairs of 128-bit halves, 256-bit halves) and 8 vector
stores. The columns past the last (``rem < 8``) are masked: ``llvm.masked.load`` and
``llvm.masked.store`` neither read nor write them (no fault at the end of an array).

Pure data movement: the results are the same bits as the loops'.

* :func:`tile_in` ``(src, base, stride, rem, dst, offs, c0, add)``: rows ``r = 0..7`` of ``src``
  at ``base + r * stride``, columns ``0..rem - 1`` of them, go to ``dst[offs[c0 + i] + add + r]``
  (column ``i`` as one vector of 8). ``offs`` has 8 entries from ``c0`` on; those past ``rem`` point
  to a spare row of ``dst`` (they receive the masked, zero lanes).
* :func:`tile_out` ``(src, offs, c0, add, dst, base, stride, rem)``: the other way: vectors
  ``src[offs[c0 + i] + add ..][:8]`` for ``i = 0..7`` (any valid offset past ``rem``: they are not
  stored) go to rows ``r = 0..7`` of ``dst`` at ``base + r * stride``, columns ``0..rem - 1``.

No bounds checks: the callers (:func:`block_transposes`) pass whole blocks only.

**The angles.** Step 2 of the kernels that vectorise across samples, written once for both families and both dimensions.

Per link, a loop over the samples of a block (the layout above: the link's
rows of ``W`` start at ``w``, a row is ``B`` samples): ``sin``/``cos`` of the link's angles (``phi``;
in 3D ``psi`` too) in branch-free arithmetic (:func:`exo_bench.models.machine.fast_trig.sincos_reduced`), stored
in the rows ``CF, SF`` (``CP, SP``), then ``link(W, w + s, B, x, cos phi, sin phi, cos psi, sin psi)``:
the family's element step for sample ``s``, which stores the link's ``kappa`` (``x`` is its own number,
the link's sign for newton-euler; it reads the link's states with :func:`states_3d` or :func:`states_2d`).
An angle beyond the arithmetic's range (or NaN) counts as outside: :func:`libm_pass` then redoes its
samples with libm's ``sin``/``cos``, a scalar loop that only they enter.

The kernels (``matrix-factored``'s :mod:`exo_bench.matrix_method.numba_kernels.simd` and
``newton-euler``'s :mod:`exo_bench.models.newton_euler.simd`) pass ``dim`` and ``link`` as constants
of their per-dimension closures. The functions here are inlined into them in numba's IR
(``register_jitable(inline="always")``): the branches on ``dim`` fold away and every loop over the
samples compiles as if written out for its dimension (planar: no ``psi``, no trig of it).
"""

from __future__ import annotations

import math
import threading
import time

import numba
import numpy as np
from exo_bench.models.machine.fast_trig import RANGE, sincos_reduced
from exo_bench.models.machine.numba_runtime import JIT, RUNTIME, ensure, jit_for
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, register_jitable

#: doubles per SIMD tile side
TILE = 8

_I32, _I64 = ir.IntType(32), ir.IntType(64)
_V = ir.VectorType(ir.DoubleType(), TILE)
_MASK = ir.VectorType(ir.IntType(1), TILE)


def _shuffle(b, x, y, lanes):
    return b.shuffle_vector(x, y, ir.Constant(ir.VectorType(_I32, TILE), lanes))


def transpose_network(b, rows: list) -> list:
    """The 8 columns of the 8 row vectors ``rows`` (IR values): doubles of rows ``2a, 2a + 1``
    interleaved, then pairs of them, then halves."""
    lo, hi = [0, 8, 2, 10, 4, 12, 6, 14], [1, 9, 3, 11, 5, 13, 7, 15]
    t = []
    for a in range(0, TILE, 2):
        t += [_shuffle(b, rows[a], rows[a + 1], lo), _shuffle(b, rows[a], rows[a + 1], hi)]
    pair_lo, pair_hi = [0, 1, 8, 9, 4, 5, 12, 13], [2, 3, 10, 11, 6, 7, 14, 15]
    u = [None] * TILE
    for h in (0, 4):
        u[h], u[h + 2] = _shuffle(b, t[h], t[h + 2], pair_lo), _shuffle(b, t[h], t[h + 2], pair_hi)
        u[h + 1], u[h + 3] = _shuffle(b, t[h + 1], t[h + 3], pair_lo), _shuffle(b, t[h + 1], t[h + 3], pair_hi)
    half_lo, half_hi = [0, 1, 2, 3, 8, 9, 10, 11], [4, 5, 6, 7, 12, 13, 14, 15]
    cols = [None] * TILE
    for i in range(4):
        cols[i], cols[4 + i] = _shuffle(b, u[i], u[4 + i], half_lo), _shuffle(b, u[i], u[4 + i], half_hi)
    return cols


def _mask(b, rem):
    """Lanes ``0..rem - 1`` on."""
    r = b.insert_element(ir.Constant(ir.VectorType(_I64, TILE), None), rem, ir.Constant(_I32, 0))
    r = _shuffle(b, r, r, [0] * TILE)
    return b.icmp_signed("<", ir.Constant(ir.VectorType(_I64, TILE), list(range(TILE))), r)


def _vector_at(b, data, idx):
    return b.bitcast(b.gep(data, [idx]), _V.as_pointer())


def _strided(b, base, stride, r):
    return b.add(base, b.mul(stride, ir.Constant(_I64, r)))


def _offset(b, offs, c0, i, add):
    return b.add(b.load(b.gep(offs, [b.add(c0, ir.Constant(_I64, i))])), add)


def _data(context, b, typ, value):
    return context.make_array(typ)(context, b, value).data


def _tile_move(gather: bool):
    """The code of :func:`tile_in` (``gather``: masked loads of the strided rows of ``src``, stores of
    columns at offsets of ``dst``) or :func:`tile_out` (loads at offsets of ``src``, masked stores
    of rows into ``dst``); both take ``(src, *its address, dst, *its address)``, the strided side's
    address ``(base, stride, rem)``, the offset side's ``(offs, c0, add)``."""

    def codegen(context, b, signature, args):
        src, dst = (_data(context, b, signature.args[k], args[k]) for k in (0, 4))
        at = 5 if gather else 1  # the offset side's arguments, the strided side's the others
        offs_, c0_, add_ = args[at : at + 3]
        base_, stride_, rem_ = args[6 - at : 9 - at]
        o = _data(context, b, signature.args[at], offs_)
        strided, packed = (src, dst) if gather else (dst, src)
        mask, align = _mask(b, rem_), ir.Constant(_I32, 8)
        if gather:
            load = cgutils.get_or_insert_function(
                b.module, ir.FunctionType(_V, [_V.as_pointer(), _I32, _MASK, _V]), "llvm.masked.load.v8f64.p0"
            )
            zero = ir.Constant(_V, None)
            rows = [
                b.call(load, [_vector_at(b, strided, _strided(b, base_, stride_, r)), align, mask, zero])
                for r in range(TILE)
            ]
            for i, col in enumerate(transpose_network(b, rows)):
                b.store(col, _vector_at(b, packed, _offset(b, o, c0_, i, add_)), align=8)
        else:
            store = cgutils.get_or_insert_function(
                b.module,
                ir.FunctionType(ir.VoidType(), [_V, _V.as_pointer(), _I32, _MASK]),
                "llvm.masked.store.v8f64.p0",
            )
            cols = [b.load(_vector_at(b, packed, _offset(b, o, c0_, i, add_)), align=8) for i in range(TILE)]
            for r, row in enumerate(transpose_network(b, cols)):
                b.call(store, [row, _vector_at(b, strided, _strided(b, base_, stride_, r)), align, mask])
        return context.get_dummy_value()

    return codegen


@intrinsic
def tile_in(typingctx, src, base, stride, rem, dst, offs, c0, add):
    return types.void(src, base, stride, rem, dst, offs, c0, add), _tile_move(True)


@intrinsic
def tile_out(typingctx, src, offs, c0, add, dst, base, stride, rem):
    return types.void(src, offs, c0, add, dst, base, stride, rem), _tile_move(False)


ensure()  # numba's runtime set-up (models/machine/numba_runtime.py), before the kernels below are defined
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
    :data:`~exo_bench.models.machine.simd_blocks.TILE`): ``scratch(n, blocks) -> W, F, T``, ``rows_in(q, qd,
    qdd, s0, m, n, blocks, W, T)`` and ``rows_out(o, s0, m, n, blocks, F, T)``.

    A whole block (``m == lanes``, a constant where the kernel inlines them) moves in tiles of 8
    samples x 8 columns through SIMD registers (:mod:`exo_bench.models.machine.simd_blocks`); a partial block
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


_inline = register_jitable(inline="always")


@_inline
def link_pass(W, w, m, B, dim, link, x):
    """The ``m`` samples of the link whose rows start at ``w``: fast ``sin``/``cos``, then ``link``;
    the number of angles beyond the range (NaN too), whose samples :func:`libm_pass` redoes."""
    outside = 0
    for s in range(m):
        phi, psi = W[w + PHI * B + s], W[w + PSI * B + s] if dim == 3 else 0.0
        okf, okp = abs(phi) <= RANGE, abs(psi) <= RANGE
        sf, cf = sincos_reduced(phi if okf else 0.0)
        sp, cp = sincos_reduced(psi if okp else 0.0) if dim == 3 else (0.0, 1.0)
        outside += (0 if okf else 1) + (0 if okp else 1)
        W[w + CF * B + s], W[w + SF * B + s] = cf, sf
        if dim == 3:
            W[w + CP * B + s], W[w + SP * B + s] = cp, sp
        link(W, w + s, B, x, cf, sf, cp, sp)
    return outside


@_inline
def libm_pass(W, w, m, B, dim, link, x):
    """The samples of :func:`link_pass`'s link with an angle beyond the range, again with libm's ``sin``/``cos``."""
    for s in range(m):
        phi, psi = W[w + PHI * B + s], W[w + PSI * B + s] if dim == 3 else 0.0
        if not (abs(phi) <= RANGE and abs(psi) <= RANGE):
            cf, sf, cp, sp = math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi)
            W[w + CF * B + s], W[w + SF * B + s] = cf, sf
            if dim == 3:
                W[w + CP * B + s], W[w + SP * B + s] = cp, sp
            link(W, w + s, B, x, cf, sf, cp, sp)


@_inline
def states_3d(W, at, B):
    """Sample ``at`` of a spatial link: ``l, phi', psi', l', phi'', psi'', l''`` (what its ``kappa`` takes)."""
    return (
        W[at + LEN * B],
        W[at + W1 * B],
        W[at + V1 * B],
        W[at + L1 * B],
        W[at + W2 * B],
        W[at + V2 * B],
        W[at + L2 * B],
    )


@_inline
def states_2d(W, at, B):
    """Sample ``at`` of a planar link (phi in row 0, l in row 1): ``l, phi', l', phi'', l''``."""
    return W[at + LEN2 * B], W[at + W1 * B], W[at + L1_2 * B], W[at + W2 * B], W[at + L2_2 * B]
