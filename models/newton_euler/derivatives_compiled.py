"""The analytic derivatives of inverse dynamics, compiled (numba): per sample, and threads over samples for
batches. The algorithm is :mod:`exo_bench.models.newton_euler.derivatives`'s; numpy's reference is
:mod:`.derivatives_numpy`.

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
   the whole row, 4 columns at a time (:mod:`.derivatives_rows`): ``dim`` rows of ``Y`` read contiguously,
   contiguous rows written; then the diagonal blocks of ``dtau/dq`` gain ``P``. Whole rows, not ``dim``
   loops of ``n``: exo5-3d's blocks took 1.28 us of CPU per sample in ``dim`` loops of 5 (with a view per
   loop), 0.50 us in one numba loop of 15 per row, 0.38 by :mod:`.derivatives_rows`; chain 100 3D 127 ->
   92-98 us (out in cache).

Work per sample: ``3 dim^2 n^2`` entries of ``dim`` multiply-adds and one product, the size of the output;
the passes and the per-rod columns are O(n). A large batch is bound by writing that output (chain 100 3D:
2.16 MB per sample, 92-115 us of arithmetic in cache): over
:data:`exo_bench.models.newton_euler.derivatives_streaming.STREAM_MIN_BYTES` of output the batched drivers
take :func:`_streamed_blocks`, the same rows streamed past the caches (:mod:`.derivatives_streaming`). Scratch (per thread): ``W (n, 16)``, ``Y (9, 3n)``,
``P (9, n)``, ``tau (dof,)``, ``m (dof,)``; the one-sample entry (:func:`derivatives_one`) takes them and
the mechanism's numbers in one packed array (:func:`workspace`): each array argument of a compiled
entry costs its unboxing (about 0.1 us), so 7 arrays instead of 14.

numba's on-disk cache keys these kernels on every module of this folder (:mod:`exo_bench.models.machine.numba_cache`).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.newton_euler.compiled import WIDTH, _inverse_sample
from exo_bench.models.newton_euler.derivatives_rows import rows_2d, rows_3d
from exo_bench.models.newton_euler.derivatives_streaming import store_fence, stream_row
from exo_bench.models.machine.numba_cache import inline
from exo_bench.models.machine.numba_runtime import JIT, SAMPLES_PER_TASK, ensure

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
    (:mod:`.derivatives_rows`), then ``P`` on the diagonal. No view and no call of a compiled function
    inside: each would count references by an atomic instruction (exo5-3d: 0.91 us per sample with a view
    of each output row and of the rows of ``Y``, 0.54 with 2D indices, 0.38 with the rows of
    :mod:`.derivatives_rows`; the same operations, the same bits)."""
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
    (:mod:`.derivatives_streaming`). One output at a time, its rows in order: the streamed lines are
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
    ``stream``: by streaming stores (:mod:`.derivatives_streaming`; :func:`streams` decides)."""
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
