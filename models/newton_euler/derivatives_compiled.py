"""The analytic derivatives of inverse dynamics, compiled (numba): per sample, and threads over samples for
batches, with the explicit SIMD output rows and the streaming stores that write them (one kernel).
The algorithm and numpy's reference are :mod:`exo_bench.models.newton_euler.derivatives`'.

Per sample:

1. **the passes** of newton-euler's own per-sample kernel
   (:func:`exo_bench.models.newton_euler.compiled._inverse_sample`, into a scratch ``tau``): each link's row
   of ``W`` then holds its cosines and sines, ``kappa``, ``A`` (with ``g up``) and the finished subtree sum
   ``D``, from which ``F_k = eta A_k + zeta kappa_k + D_k``
   (:func:`exo_bench.models.mechanism.rod_elements.rod_force`) is recomputed bit for bit;
2. **per rod** the signed columns of :mod:`.derivative_elements` into ``Y``, laid out like a row of the
   output: row ``kind dim + e``, column ``d n + j`` holds component ``e`` of column ``d`` of ``s_j J_j``
   (kind 0), ``s_j da_j/dq_j`` (1) or ``s_j da_j/dqd_j`` (2); ``s_i d(J_i^T F_i)/dq_i`` into ``P``;
3. **the blocks**: for each row link ``i``, ``mu_i`` repeated ``dim`` times (``m[d n + j] = mu_ij``), then
   per kind the ``dim`` output rows ``out[c n + i, :] = m * ((J_i^T)[c, :] . Y_kind)`` in one loop over
   the whole row, 4 columns at a time (:func:`rows_3d`, :func:`rows_2d`): ``dim`` rows of ``Y`` read contiguously,
   contiguous rows written; then the diagonal blocks of ``dtau/dq`` gain ``P``. Whole rows, not ``dim``
   loops of ``n``: exo5-3d's blocks took 1.28 us of CPU per sample in ``dim`` loops of 5 (with a view per
   loop), 0.50 us in one numba loop of 15 per row, 0.38 by the explicit rows; chain 100 3D 127 ->
   92-98 us (out in cache).

Work per sample: ``3 dim^2 n^2`` entries of ``dim`` multiply-adds and one product, the size of the output;
the passes and the per-rod columns are O(n). A large batch is bound by writing that output (chain 100 3D:
2.16 MB per sample, 92-115 us of arithmetic in cache): over
:data:`STREAM_MIN_BYTES` of output the batched drivers
take :func:`_streamed_blocks`, the same rows streamed past the caches (:func:`stream_row`). Scratch (per thread): ``W (n, 16)``, ``Y (9, 3n)``,
``P (9, n)``, ``tau (dof,)``, ``m (dof,)``; the one-sample entry (:func:`derivatives_one`) takes them and
the mechanism's numbers in one packed array (:func:`workspace`): each array argument of a compiled
entry costs its unboxing (about 0.1 us), so 7 arrays instead of 14.

numba's on-disk cache keys these kernels on every module of this folder (:mod:`exo_bench.models.machine.numba_cache`).

**The output rows** of one link, as explicit 4-wide SIMD code: numba intrinsics (LLVM IR written here)
used by :func:`_blocks`.

For row link ``i`` the ``dim`` rows ``r_c = c n + i`` (``c < dim``) of one output are ``o[r_c, k] = m[k] *
(z_c0 Y[e, k] + z_c1 Y[e + 1, k] (+ z_c2 Y[e + 2, k]))`` (``z_cu``: component ``u`` of column ``c`` of ``s_i
J_i``; ``m``: row ``i`` of ``mu`` repeated; ``Y[e..]``: the signed columns of one kind). :func:`rows_3d` and
:func:`rows_2d` write them in one loop over 4 columns at a time, each load of ``m`` and ``Y`` shared by the
``dim`` rows, the last 4 columns overlapping the previous ones when ``dof`` is not a multiple of 4 (the
same values written twice; the outputs never overlap ``m`` or ``Y``, which are the kernel's scratch), and a
loop of one column at a time when ``dof < 4``.

**Why not a numba loop.** Written as ``for k in range(dof)`` per row, LLVM vectorises each row with a
16-wide main body (4 vectors interleaved), a 4-wide remainder loop, scalar leftovers and a runtime
check that the output row does not alias ``m`` and ``Y`` (numba cannot tell LLVM that arrays are apart):
at exo5-3d's rows of 15 the main body never runs and the checks and leftovers cost more than the
arithmetic. numba leaves LLVM's SLP vectoriser off, so four columns written out by hand stay scalar. Here:
exo5-3d, 256 samples, one thread (CPU of the blocks alone, load 8): 0.54 us per sample by the numba
loops, 0.38 by these rows.

The same operations in the same order as the loops (``m * ((z0 y0 + z1 y1) + z2 y2)``, IEEE products and
sums, no fused multiply-add): the same bits. Under ``NUMBA_DISABLE_JIT`` (an intrinsic has no Python form)
:data:`rows_3d` and :data:`rows_2d` are those loops in Python (:func:`rows_python`).

**Streaming stores** of the output rows: each row of ``dtau/dq``, ``dtau/dqd`` and ``M`` is
written past the caches (non-temporal stores), for batches whose output is larger than the caches.

**Why stream.** The per-sample kernel computes an output row from arrays that
stay in L1 (``Y``, ``mu``), so a large batch is bound by writing its output: chain 100 in 3D writes
2.16 MB per sample. An ordinary store first reads the cache line it writes (read for ownership): the
memory carries every byte twice. A non-temporal store sends whole lines to memory without reading them.
Measured on this 2-core host (load about 8, best of 10, a 134 MB batch of 300 x 300 rows computed as
the kernel does): ordinary stores 0.20-0.30 ms per 720 kB, numpy's ``fill`` 0.12-0.18, these stores
0.071. Results in cache are different: a later read of a streamed row comes from memory, so only
batches of at least :data:`STREAM_MIN_BYTES` of output stream (:func:`streams`).

**How it streams.** The kernel computes each output row as before, into a scratch row in L1 (the same loop, the
same bits), and :func:`stream_row` copies it out. numba has no non-temporal store; :func:`stream_row` is
an intrinsic (``numba.extending.intrinsic``, LLVM IR by llvmlite) that loads 4 (or 2) entries at a time and
stores them with LLVM's ``!nontemporal`` hint (``movntpd`` on x86). The store is declared 16-byte aligned, so
:func:`streams` admits only outputs whose rows all start 16-byte aligned (an even ``dof`` and
16-aligned bases); anything else takes the ordinary loop. :func:`store_fence` (``fence seq_cst``,
``mfence`` on x86) orders the streamed stores before the kernel returns: non-temporal stores are weakly
ordered, and another thread may read the output next.
"""

from __future__ import annotations

import numpy as np
from exo_bench.models.machine.numba_cache import inline
from exo_bench.models.machine.numba_runtime import JIT, SAMPLES_PER_TASK, ensure, jit_disabled
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.newton_euler.compiled import WIDTH, _inverse_sample
from llvmlite import ir
from numba import njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

ensure()  # numba's runtime set-up, before the kernels below are defined

#: A call whose output takes at least this many bytes streams its rows: half of this host's 32 MiB
#: L3; a smaller output stays in cache for the caller's next read (exo5-3d, 256 samples: 0.17 MB).
STREAM_MIN_BYTES = 2**24
_ALIGN = 16  # bytes: the alignment the vector store declares (two float64)


def _vector_copy(context, builder, vty, src, dst, at):
    """Lanes ``at ..`` of ``src`` stored non-temporally at ``dst``'s ``at ..`` (pointers to float64)."""
    value = builder.load(builder.bitcast(builder.gep(src, [at]), vty.as_pointer()), align=8)
    store = builder.store(value, builder.bitcast(builder.gep(dst, [at]), vty.as_pointer()), align=_ALIGN)
    store.set_metadata("nontemporal", builder.module.add_metadata([ir.Constant(ir.IntType(32), 1)]))


@intrinsic
def stream_row(typingctx, out, start, a):
    """``out.flat[start : start + len(a)] = a`` by streaming stores, in blocks of 4 and one of 2: ``out``
    C-contiguous with that entry 16-byte aligned, ``len(a)`` even (:func:`streams`). One loop in LLVM IR,
    no call: a call of a compiled function per row would count references to its array arguments by
    atomic (locked) instructions, and a locked instruction drains the write-combining buffers, half a
    cache line at a time (measured: 2.5 ms per sample instead of 0.95 on chain 100 3D)."""

    def codegen(context, builder, signature, args):
        oty, _, aty = signature.args
        dst = builder.gep(context.make_array(oty)(context, builder, args[0]).data, [args[1]])
        src_ary = context.make_array(aty)(context, builder, args[2])
        n = cgutils.unpack_tuple(builder, src_ary.shape, 1)[0]
        intp = n.type
        blocks = builder.sdiv(n, ir.Constant(intp, 4))
        v4, v2 = ir.VectorType(ir.DoubleType(), 4), ir.VectorType(ir.DoubleType(), 2)
        with cgutils.for_range(builder, blocks) as loop:
            _vector_copy(context, builder, v4, src_ary.data, dst, builder.mul(loop.index, ir.Constant(intp, 4)))
        done = builder.mul(blocks, ir.Constant(intp, 4))
        with builder.if_then(builder.icmp_signed("<", done, n)):
            _vector_copy(context, builder, v2, src_ary.data, dst, done)
        return context.get_dummy_value()

    return types.void(out, types.intp, a), codegen


@intrinsic
def _fence(typingctx):
    def codegen(context, builder, signature, args):
        builder.fence("seq_cst")
        return context.get_dummy_value()

    return types.void(), codegen


@njit(**JIT)
def store_fence():
    """Order every streamed store before what follows (module docstring)."""
    _fence()


def streams(outs: tuple[np.ndarray, ...], dof: int) -> bool:
    """Whether a call writing ``outs`` (C-contiguous float64, rows of ``dof``) streams its rows: at least
    :data:`STREAM_MIN_BYTES` of output, every row 16-byte aligned (even ``dof``, aligned bases), and
    compiled kernels (an intrinsic has no Python form under ``NUMBA_DISABLE_JIT``)."""
    from exo_bench.models.machine.numba_runtime import jit_disabled

    if dof % 2 or sum(o.nbytes for o in outs) < STREAM_MIN_BYTES or jit_disabled():
        return False
    return all(o.ctypes.data % _ALIGN == 0 for o in outs)


_I32, _I64 = ir.IntType(32), ir.IntType(64)
_V4 = ir.VectorType(ir.DoubleType(), 4)
_W = 4  # columns per step


def _splat(b, x):
    v = b.insert_element(ir.Constant(_V4, None), x, ir.Constant(_I32, 0))
    return b.shuffle_vector(v, v, ir.Constant(ir.VectorType(_I32, _W), [0] * _W))


def _combine(b, mk, ys, zs):
    """``mk * ((z0 y0 + z1 y1) + z2 y2)``, in the loops' order (scalars or vectors alike)."""
    acc = b.fmul(zs[0], ys[0])
    for y, z in zip(ys[1:], zs[1:]):
        acc = b.fadd(acc, b.fmul(z, y))
    return b.fmul(mk, acc)


def _codegen(dim: int):
    """The code of :func:`rows_3d` (``dim = 3``) or :func:`rows_2d`: arguments ``(o, i, m, Y, n, e, z...)``,
    ``z[c dim + u]`` component ``u`` of column ``c``."""

    def codegen(context, b, sig, args):
        o, m, Y = (context.make_array(sig.args[k])(context, b, args[k]) for k in (0, 2, 3))
        i, n, e, z = args[1], args[4], args[5], args[6 : 6 + dim * dim]
        ncol = cgutils.unpack_tuple(b, o.shape, 2)[1]
        ystride = cgutils.unpack_tuple(b, Y.shape, 2)[1]
        const = lambda v: ir.Constant(_I64, v)  # noqa: E731
        dsts = [b.gep(o.data, [b.mul(b.add(b.mul(const(c), n), i), ncol)]) for c in range(dim)]
        rows = [b.gep(Y.data, [b.mul(b.add(e, const(u)), ystride)]) for u in range(dim)]

        def step(k, load, zs):
            ys = [load(p, k) for p in rows]
            mk = load(m.data, k)
            return [_combine(b, mk, ys, zs[c * dim : (c + 1) * dim]) for c in range(dim)]

        def vector_at(p, k):
            return b.bitcast(b.gep(p, [k]), _V4.as_pointer())

        with b.if_else(b.icmp_signed(">=", ncol, const(_W))) as (wide, narrow):
            with wide:
                zv = [_splat(b, x) for x in z]
                last = b.sub(ncol, const(_W))
                with cgutils.for_range(b, b.sdiv(b.add(ncol, const(_W - 1)), const(_W))) as loop:
                    k = b.mul(loop.index, const(_W))
                    k = b.select(b.icmp_signed(">", k, last), last, k)
                    for dst, v in zip(dsts, step(k, lambda p, k: b.load(vector_at(p, k), align=8), zv)):
                        b.store(v, vector_at(dst, k), align=8)
            with narrow:
                with cgutils.for_range(b, ncol) as loop:
                    k = loop.index
                    for dst, v in zip(dsts, step(k, lambda p, k: b.load(b.gep(p, [k])), z)):
                        b.store(v, b.gep(dst, [k]))
        return context.get_dummy_value()

    return codegen


@intrinsic
def _rows_3d(typingctx, o, i, m, Y, n, e, z00, z01, z02, z10, z11, z12, z20, z21, z22):
    sig = types.void(o, i, m, Y, n, e, z00, z01, z02, z10, z11, z12, z20, z21, z22)
    return sig, _codegen(3)


@intrinsic
def _rows_2d(typingctx, o, i, m, Y, n, e, z00, z01, z10, z11):
    return types.void(o, i, m, Y, n, e, z00, z01, z10, z11), _codegen(2)


def rows_python(o, i, m, Y, n, e, *z) -> None:
    """The rows as the numba loops wrote them (module docstring), for ``NUMBA_DISABLE_JIT``."""
    dim = 3 if len(z) == 9 else 2
    for c in range(dim):
        r = c * n + i
        for k in range(o.shape[1]):
            acc = z[c * dim] * Y[e, k] + z[c * dim + 1] * Y[e + 1, k]
            if dim == 3:
                acc = acc + z[c * dim + 2] * Y[e + 2, k]
            o[r, k] = m[k] * acc


#: ``rows_3d(o, i, m, Y, n, e, z00, z01, z02, z10, ..., z22)`` and ``rows_2d(o, i, m, Y, n, e, z00, z01,
#: z10, z11)``: the intrinsics, or :func:`rows_python` under ``NUMBA_DISABLE_JIT`` (fixed at import).
rows_3d = rows_python if jit_disabled() else _rows_3d
rows_2d = rows_python if jit_disabled() else _rows_2d

ensure()  # numba's runtime set-up, before the kernels below are defined
inline(de.DERIVATIVE_ELEMENTS, de.__file__.rsplit("/", 1)[0])

_SIGN, _ZETA, _ETA = 1, 2, 3
_TRIG, _KAPPA, _A, _D = 0, 4, 7, 10
_J, _AQ, _AR = 0, 1, 2  # kinds of the rows of Y


def scratch(n: int, dim: int):
    """One thread's scratch ``(W, Y, P, tau, m)`` of :func:`derivatives_sample` (module docstring)."""
    return np.zeros((n, WIDTH)), np.zeros((9, 3 * n)), np.zeros((9, n)), np.zeros(dim * n), np.zeros(dim * n)


def workspace(table: np.ndarray, mu: np.ndarray, dim: int) -> np.ndarray:
    """The packed argument of :func:`derivatives_one`: ``[table (8, n), mu (n, n), W, Y, P, tau, m]``
    flat (:func:`_unpack`), one per thread (the scratch is written)."""
    n = table.shape[1]
    return np.concatenate([table.reshape(-1), mu.reshape(-1), *(a.reshape(-1) for a in scratch(n, dim))])


@njit(**JIT)
def _unpack(ws, n, dim):
    """The views of a :func:`workspace`: ``t, mu, W, Y, P, tau, m``."""
    a = 8 * n
    b = a + n * n
    c = b + n * WIDTH
    d = c + 27 * n
    e = d + 9 * n
    f = e + dim * n
    t, mu = ws[:a].reshape((8, n)), ws[a:b].reshape((n, n))
    W, Y, P = ws[b:c].reshape((n, WIDTH)), ws[c:d].reshape((9, 3 * n)), ws[d:e].reshape((9, n))
    return t, mu, W, Y, P, ws[e:f], ws[f : f + dim * n]


@njit(**JIT)
def _columns(t, dim, x, xd, xdd, W, Y, P):
    """2. Per rod: the signed columns into ``Y`` and ``s_k d(J_k^T F_k)/dq_k`` into ``P`` (``W`` after the passes)."""
    n = t.shape[1]
    for k in range(n):
        w = W[k]
        s, zeta, eta = t[_SIGN, k], t[_ZETA, k], t[_ETA, k]
        f0 = el.rod_force(zeta, eta, w[_A], w[_KAPPA], w[_D])
        f1 = el.rod_force(zeta, eta, w[_A + 1], w[_KAPPA + 1], w[_D + 1])
        f2 = el.rod_force(zeta, eta, w[_A + 2], w[_KAPPA + 2], w[_D + 2])
        cf, sf, cp, sp = w[0], w[1], w[2], w[3]
        if dim == 2:
            l, wr, lr, wa, la = x[n + k], xd[k], xd[n + k], xdd[k], xdd[n + k]
            jac = de.jacobian_2d(cf, sf, l)
            aq = de.acceleration_by_q_2d(cf, sf, l, wr, lr, wa, la)
            ar = de.acceleration_by_rates_2d(cf, sf, l, wr, lr)
            pq = de.projection_by_q_2d(cf, sf, l, f0, f1)
            for r in range(4):  # r = d dim + e: component e of column d
                col = (r // 2) * n + k
                Y[r % 2, col] = s * jac[r]
                Y[2 + r % 2, col] = s * aq[r]
                Y[4 + r % 2, col] = s * ar[r]
                P[r, k] = s * pq[r]
        else:
            l, wr, vr, lr = x[2 * n + k], xd[k], xd[n + k], xd[2 * n + k]
            jac = de.jacobian_3d(cf, sf, cp, sp, l)
            aq = de.acceleration_by_q_3d(cf, sf, cp, sp, l, wr, vr, lr, xdd[k], xdd[n + k], xdd[2 * n + k])
            ar = de.acceleration_by_rates_3d(cf, sf, cp, sp, l, wr, vr, lr)
            pq = de.projection_by_q_3d(cf, sf, cp, sp, l, f0, f1, f2)
            for r in range(9):
                col = (r // 3) * n + k
                Y[r % 3, col] = s * jac[r]
                Y[3 + r % 3, col] = s * aq[r]
                Y[6 + r % 3, col] = s * ar[r]
                P[r, k] = s * pq[r]


@njit(**JIT)
def _blocks(mu, dim, Y, P, oq, oqd, om, m):
    """3. Every block ``mu_ij J_i^T Y_j`` into the three ``(dof, dof)`` outputs (module docstring; ``m``:
    ``(dof,)`` scratch), the ``dim`` rows of each row link written together, 4 columns at a time
    (:mod:`.derivatives_compiled`), then ``P`` on the diagonal. No view and no call of a compiled function
    inside: each would count references by an atomic instruction (exo5-3d: 0.91 us per sample with a view
    of each output row and of the rows of ``Y``, 0.54 with 2D indices, 0.38 with the rows of
    :mod:`.derivatives_compiled`; the same operations, the same bits)."""
    n = mu.shape[0]
    for i in range(n):
        for d in range(dim):
            for j in range(n):
                m[d * n + j] = mu[i, j]
        # column c of s_i J_i (row c of s_i J_i^T): its components in rows 0..dim-1 of Y, at column c n + i
        if dim == 3:
            a0, a1, a2 = Y[0, i], Y[1, i], Y[2, i]
            b0, b1, b2 = Y[0, n + i], Y[1, n + i], Y[2, n + i]
            c0, c1, c2 = Y[0, 2 * n + i], Y[1, 2 * n + i], Y[2, 2 * n + i]
            rows_3d(om, i, m, Y, n, 3 * _J, a0, a1, a2, b0, b1, b2, c0, c1, c2)
            rows_3d(oq, i, m, Y, n, 3 * _AQ, a0, a1, a2, b0, b1, b2, c0, c1, c2)
            rows_3d(oqd, i, m, Y, n, 3 * _AR, a0, a1, a2, b0, b1, b2, c0, c1, c2)
        else:
            a0, a1, b0, b1 = Y[0, i], Y[1, i], Y[0, n + i], Y[1, n + i]
            rows_2d(om, i, m, Y, n, 2 * _J, a0, a1, b0, b1)
            rows_2d(oq, i, m, Y, n, 2 * _AQ, a0, a1, b0, b1)
            rows_2d(oqd, i, m, Y, n, 2 * _AR, a0, a1, b0, b1)
        for c in range(dim):
            for d in range(dim):
                oq[c * n + i, d * n + i] += P[d * dim + c, i]


@njit(**JIT)
def _streamed_blocks(mu, dim, Y, P, oq, oqd, om, m, row):
    """:func:`_blocks` for outputs larger than the caches: each row computed into the scratch ``row`` with
    the same operations (the same bits), ``P`` added on its diagonal, then streamed out
    (:mod:`.derivatives_compiled`). One output at a time, its rows in order: the streamed lines are
    written in sequence (a row of 300 float64 ends inside a cache line, which the next row completes)."""
    n = mu.shape[0]
    dof = dim * n
    for kind in range(3):  # no view and no call inside the loops below: each counts references atomically
        out = om if kind == _J else (oq if kind == _AQ else oqd)
        g0, g1, g2 = Y[dim * kind], Y[dim * kind + 1], Y[dim * kind + 2 if dim == 3 else dim * kind + 1]
        for c in range(dim):
            for i in range(n):
                for d in range(dim):
                    for j in range(n):
                        m[d * n + j] = mu[i, j]
                col = c * n + i
                z0, z1 = Y[0, col], Y[1, col]
                if dim == 3:
                    z2 = Y[2, col]
                    for k in range(dof):
                        row[k] = m[k] * (z0 * g0[k] + z1 * g1[k] + z2 * g2[k])
                else:
                    for k in range(dof):
                        row[k] = m[k] * (z0 * g0[k] + z1 * g1[k])
                if kind == _AQ:
                    for d in range(dim):
                        row[d * n + i] += P[d * dim + c, i]
                stream_row(out, col * dof, row)


@njit(**JIT)
def derivatives_sample(t, mu, g, dim, x, xd, xdd, oq, oqd, om, W, Y, P, tau, m, row, stream):
    """One sample: flat ``(dof,)`` states, ``(dof, dof)`` outputs; ``(W, Y, P, tau, m)`` from :func:`scratch`;
    ``stream``: rows streamed out through the ``(dof,)`` scratch ``row`` (:func:`_streamed_blocks`)."""
    _inverse_sample(t, g, dim, x, xd, xdd, tau, 0, W)
    _columns(t, dim, x, xd, xdd, W, Y, P)
    if stream:
        _streamed_blocks(mu, dim, Y, P, oq, oqd, om, m, row)
    else:
        _blocks(mu, dim, Y, P, oq, oqd, om, m)


@njit(**JIT)
def _overlap(a, b):
    """Arrays ``a`` and ``b`` (float64, contiguous) share bytes: their extents intersect."""
    a0, b0 = a.ctypes.data, b.ctypes.data
    return a0 < b0 + 8 * b.size and b0 < a0 + 8 * a.size


@njit(**JIT)
def _unsafe(n, dim, x, xd, xdd, oq, oqd, om):
    """The check of memory safety of the one-sample entries, nanoseconds: 0, or ``k + 1`` where output
    ``k`` is not ``(dof, dof)`` or overlaps a state or an earlier output, or 4 where a state is not ``(dof,)``."""
    dof = dim * n
    if x.shape[0] != dof or xd.shape[0] != dof or xdd.shape[0] != dof:
        return 4
    outs = (oq, oqd, om)
    for k in range(3):
        o = outs[k]
        if o.shape[0] != dof or o.shape[1] != dof:
            return k + 1
        if _overlap(o, x) or _overlap(o, xd) or _overlap(o, xdd):
            return k + 1
        for j in range(k):
            if _overlap(o, outs[j]):
                return k + 1
    return 0


@njit(**JIT)
def derivatives_one(ws, n, g, dim, x, xd, xdd, oq, oqd, om):
    """:func:`derivatives_sample` on a :func:`workspace` ``ws``, behind :func:`_unsafe` (nothing is
    written where it answers, and the caller names why). The one-sample entry of
    :class:`exo_bench.models.newton_euler.derivatives.InverseDerivatives`."""
    code = _unsafe(n, dim, x, xd, xdd, oq, oqd, om)
    if code:
        return code
    t, mu, W, Y, P, tau, m = _unpack(ws, n, dim)
    derivatives_sample(t, mu, g, dim, x, xd, xdd, oq, oqd, om, W, Y, P, tau, m, m, False)  # not streamed: in cache
    return 0


@njit(**JIT)
def _plain(a):
    """A one-dimensional array (typed C-ordered by the caller's entry point) whose entries lie 8 bytes apart, aligned."""
    return a.strides[0] == 8 and a.ctypes.data % 8 == 0


@njit(**JIT)
def _range(t, mu, g, dim, q, qd, qdd, oq, oqd, om, stream, start, stop):
    """Samples ``start .. stop - 1`` of ``(S, dof)`` states into ``(S, dof, dof)`` outputs (scratch once);
    ``stream``: by streaming stores (:mod:`.derivatives_compiled`; :func:`streams` decides)."""
    n = t.shape[1]
    W, Y, P = np.zeros((n, WIDTH)), np.zeros((9, 3 * n)), np.zeros((9, n))
    tau, m, row = np.zeros(dim * n), np.zeros(dim * n), np.zeros(dim * n)
    for s in range(start, stop):
        derivatives_sample(t, mu, g, dim, q[s], qd[s], qdd[s], oq[s], oqd[s], om[s], W, Y, P, tau, m, row, stream)
    if stream:
        store_fence()


@njit(**JIT)
def derivatives_serial(t, mu, g, dim, q, qd, qdd, oq, oqd, om, stream=False):
    """Every sample of a batch in turn."""
    _range(t, mu, g, dim, q, qd, qdd, oq, oqd, om, stream, 0, q.shape[0])


@njit(parallel=True, **JIT)
def derivatives_parallel(t, mu, g, dim, q, qd, qdd, oq, oqd, om, stream=False):
    """:func:`derivatives_serial` in blocks of :data:`exo_bench.models.machine.numba_runtime.SAMPLES_PER_TASK`
    samples over numba's threads."""
    S = q.shape[0]
    for b in prange((S + SAMPLES_PER_TASK - 1) // SAMPLES_PER_TASK):
        stop = min(S, (b + 1) * SAMPLES_PER_TASK)
        _range(t, mu, g, dim, q, qd, qdd, oq, oqd, om, stream, b * SAMPLES_PER_TASK, stop)
