"""Directional derivatives of inverse dynamics, compiled to vectorise across samples: the JVP and VJP of
:mod:`exo_bench.models.newton_euler.products` in blocks of :data:`~exo_bench.models.machine.simd_blocks.LANES`
samples, each step a loop over the samples of a block that LLVM turns into SIMD instructions (the layout and
the passes of newton-euler's batched inverse dynamics, :mod:`exo_bench.models.newton_euler.simd`).

Per block, O(n) per sample and no ``n x n`` array:

1. **the primal passes, once**: the transposes in of the states and of the directions (``U``, the layout
   of ``W``), newton-euler's batched forward pass (its branch-free ``sin``/``cos``, libm beyond their
   range: each rod's ``kappa_k`` and its start point's acceleration ``A_k``), and the subtree sums ``D_k``
   alone (:func:`_subtree_sums`, :func:`exo_bench.models.mechanism.rod_elements.subtree_share`: the first half of
   its backward pass; the forces ``F_k`` are then :func:`exo_bench.models.mechanism.rod_elements.rod_force` per rod);
2. **per rod, each sample a lane**, the signed per-rod columns of :mod:`.derivative_elements` (``J_k``,
   ``A^q_k``, ``A^r_k``, ``P_k``) contracted at once with the directions, never stored:

   * JVP: the change of the rod's acceleration ``A^q dq + A^r dqd + J dqdd`` over ``kappa_k`` in ``W``,
     and ``P_k dq_k`` aside (``X``);
   * VJP: ``J_k w_k`` over ``kappa_k``, and the force ``F_k`` aside (``X``);

3. **the gravity-free passes** on those accelerations, newton-euler's own (``_start_points`` of :func:`exo_bench.models.newton_euler.simd.build` at
   ``g = 0``, then for the JVP its backward pass, which leaves ``J^T dF`` where it leaves ``tau``; for the VJP
   the subtree sums again, so that the forces ``v = (mu (x) I) J w`` are ``rod_force`` per rod);
4. JVP: ``J^T dF + P dq`` transposed out. VJP, per rod: ``(A^q)^T v + P^T w``, ``(A^r)^T v`` and ``J^T v``
   (:func:`exo_bench.models.mechanism.rod_elements.project_3d` of ``v``), transposed out into the three results.

Work per sample: one inverse dynamics (its trig once), one gravity-free pass without trig, and the per-rod
elements. Its sines and cosines are the batched inverse dynamics' (:mod:`exo_bench.models.machine.fast_trig`): it
differs from the per-sample kernel (:mod:`.products`, libm's) by those and by the order of its
sums (tests/test_products_simd.py). A sample's result does not depend on the batch around it. numba's
on-disk cache of these kernels is keyed on newton_euler's folder, which holds this file and the elements'
derivatives, and on the rod elements (:data:`exo_bench.models.machine.numba_cache.KERNEL_SOURCES`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.newton_euler import simd
from exo_bench.models.machine.numba_cache import inline
from exo_bench.models.machine.numba_runtime import JIT, ensure
from exo_bench.models.machine.simd_blocks import states_2d, states_3d
from exo_bench.models.machine.simd_blocks import (
    CF,
    CP,
    F0,
    FROWS,
    K0,
    LANES,
    LEN,
    LEN2,
    O0,
    ROWS,
    SF,
    SP,
    block_transposes,
)
from exo_bench.models.machine.simd_blocks import parallel_min_samples, run

ensure()
inline(de.DERIVATIVE_ELEMENTS, de.__file__.rsplit("/", 1)[0])

B = LANES
_PARENT, _SIGN, _ZETA, _ETA, _THETA = range(5)  # rows of the tree's table (simd.py's)
_scratch_passes, _rows_in, _rows_out = block_transposes(LANES)
_forward_2d, _forward_3d = simd._WIDE._forward_2d, simd._WIDE._forward_3d
_start_points, _backward = simd._WIDE._start_points, simd._WIDE._backward
_DQ, _DQD, _DQDD = 0, 3, 6  # rows of a link's directions in U (the states' rows of W)


def scratch(n: int, dim: int):
    """One thread's scratch: the passes' ``(W, F, T)``, the directions ``U`` (``W``'s layout), ``X`` (three
    rows per link) and two more result rows ``G``, ``H`` (``F``'s layout, for the VJP's outputs)."""
    W, F, T = _scratch_passes(n, dim)
    return W, F, T, np.zeros(W.shape[0]), np.zeros(3 * n * B), np.zeros(F.shape[0]), np.zeros(F.shape[0])


@njit(**JIT)
def _subtree_sums(t, m, W, F):
    """1./3. ``D_p += theta A_k + eta kappa_k + D_k``, leaves first, over the rows ``F0..F2`` (``A_k`` in
    ``O0..O2``, ``kappa_k`` in ``K0..K2``; the rows ``F0..F2`` zero from the forward pass)."""
    for k in range(t.shape[1] - 1, -1, -1):
        p = int(t[_PARENT, k])
        if p >= 0:
            Wk, Fk = W[k * ROWS * B : (k + 1) * ROWS * B], F[k * FROWS * B : (k + 1) * FROWS * B]
            Fp, theta, eta = F[p * FROWS * B : (p + 1) * FROWS * B], t[_THETA, k], t[_ETA, k]
            for c in range(3):
                for s in range(m):
                    Fp[(F0 + c) * B + s] += el.subtree_share(
                        theta, eta, Fk[(O0 + c) * B + s], Wk[(K0 + c) * B + s], Fk[(F0 + c) * B + s]
                    )


@njit(**JIT)
def _apply_3d(Y, a, b, c):
    """``Y x`` of a ``3 x 3`` column tuple (columns of ``(x, y, z)``) and ``x = (a, b, c)``."""
    return Y[0] * a + Y[3] * b + Y[6] * c, Y[1] * a + Y[4] * b + Y[7] * c, Y[2] * a + Y[5] * b + Y[8] * c


@njit(**JIT)
def _transpose_apply_3d(Y, a, b, c):
    """``Y^T x`` of a ``3 x 3`` column tuple and ``x = (a, b, c)``."""
    return Y[0] * a + Y[1] * b + Y[2] * c, Y[3] * a + Y[4] * b + Y[5] * c, Y[6] * a + Y[7] * b + Y[8] * c


@njit(**JIT)
def _apply_2d(Y, a, b):
    return Y[0] * a + Y[2] * b, Y[1] * a + Y[3] * b


@njit(**JIT)
def _transpose_apply_2d(Y, a, b):
    return Y[0] * a + Y[1] * b, Y[2] * a + Y[3] * b


@njit(**JIT)
def _link(t, k, W, F, U, X):
    """Link ``k``'s rows of the scratch as views (their offsets folded into the pointers, so that LLVM
    vectorises the loops over the samples, as in simd.py), its sign and its ``zeta``, ``eta``."""
    Wk, Fk = W[k * ROWS * B : (k + 1) * ROWS * B], F[k * FROWS * B : (k + 1) * FROWS * B]
    Uk, Xk = U[k * ROWS * B : (k + 1) * ROWS * B], X[3 * k * B : 3 * (k + 1) * B]
    return Wk, Fk, Uk, Xk, t[_SIGN, k], t[_ZETA, k], t[_ETA, k]


@njit(**JIT)
def _forces(Fk, Wk, zeta, eta, s):
    """``F_k`` of lane ``s`` (:func:`exo_bench.models.mechanism.rod_elements.rod_force`) from the link's rows."""
    return (
        el.rod_force(zeta, eta, Fk[O0 * B + s], Wk[K0 * B + s], Fk[F0 * B + s]),
        el.rod_force(zeta, eta, Fk[(O0 + 1) * B + s], Wk[(K0 + 1) * B + s], Fk[(F0 + 1) * B + s]),
        el.rod_force(zeta, eta, Fk[(O0 + 2) * B + s], Wk[(K0 + 2) * B + s], Fk[(F0 + 2) * B + s]),
    )


@njit(**JIT)
def _primal(t, g, dim, q, qd, qdd, u0, u1, u2, s0, m, S):
    """1. States and directions in, the forward pass (trig, ``kappa``, ``A``), the subtree sums ``D``."""
    n = t.shape[1]
    W, F, T, U = S[0], S[1], S[2], S[3]
    _rows_in(q, qd, qdd, s0, m, n, dim, W, T)
    _rows_in(u0, u1, u2, s0, m, n, dim, U, T)
    if dim == 3:
        _forward_3d(t, g, m, W, F, q, qd, qdd, q, 0, 0)
    else:
        _forward_2d(t, g, m, W, F, q, qd, qdd, q, 0, 0)
    _subtree_sums(t, m, W, F)


@njit(**JIT)
def _tangent_start_points(t, dim, m, W, F):
    """3. The gravity-free forward pass on the accelerations in ``K0..K2`` (``D = 0``)."""
    for k in range(t.shape[1]):
        _start_points(t, 0.0, dim, k, m, W, F)


@njit(**JIT)
def _jvp_rods(t, dim, m, W, F, U, X):
    """2. (JVP) per rod and lane: ``A^q dq + A^r dqd + J dqdd`` over ``kappa_k``, ``P_k dq_k`` into ``X``."""
    for k in range(t.shape[1]):
        Wk, Fk, Uk, Xk, s_k, zeta, eta = _link(t, k, W, F, U, X)
        for s in range(m):
            f0, f1, f2 = _forces(Fk, Wk, zeta, eta, s)
            cf, sf = Wk[CF * B + s], Wk[SF * B + s]
            if dim == 3:
                cp, sp = Wk[CP * B + s], Wk[SP * B + s]
                l, wr, vr, lr, wa, va, la = states_3d(Wk, s, B)
                dq = (Uk[_DQ * B + s], Uk[(_DQ + 1) * B + s], Uk[(_DQ + 2) * B + s])
                dqd = (Uk[_DQD * B + s], Uk[(_DQD + 1) * B + s], Uk[(_DQD + 2) * B + s])
                dqdd = (Uk[_DQDD * B + s], Uk[(_DQDD + 1) * B + s], Uk[(_DQDD + 2) * B + s])
                a = _apply_3d(de.acceleration_by_q_3d(cf, sf, cp, sp, l, wr, vr, lr, wa, va, la), *dq)
                b = _apply_3d(de.acceleration_by_rates_3d(cf, sf, cp, sp, l, wr, vr, lr), *dqd)
                c = el.rod_acceleration_3d(cf, sf, cp, sp, l, 0.0, 0.0, 0.0, *dqdd)  # J dqdd: zero rates
                p = _transpose_apply_3d(de.projection_by_q_3d(cf, sf, cp, sp, l, f0, f1, f2), *dq)
                for e in range(3):
                    Wk[(K0 + e) * B + s] = s_k * (a[e] + b[e] + c[e])
                    Xk[e * B + s] = s_k * p[e]
            else:
                l, wr, lr, wa, la = states_2d(Wk, s, B)
                dq2 = (Uk[_DQ * B + s], Uk[(_DQ + 1) * B + s])
                dqd2 = (Uk[_DQD * B + s], Uk[(_DQD + 1) * B + s])
                dqdd2 = (Uk[_DQDD * B + s], Uk[(_DQDD + 1) * B + s])
                a2 = _apply_2d(de.acceleration_by_q_2d(cf, sf, l, wr, lr, wa, la), *dq2)
                b2 = _apply_2d(de.acceleration_by_rates_2d(cf, sf, l, wr, lr), *dqd2)
                c2 = el.rod_acceleration_2d(cf, sf, l, 0.0, 0.0, *dqdd2)
                p2 = _transpose_apply_2d(de.projection_by_q_2d(cf, sf, l, f0, f1), *dq2)
                for e in range(2):
                    Wk[(K0 + e) * B + s] = s_k * (a2[e] + b2[e] + c2[e])
                    Xk[e * B + s] = s_k * p2[e]
                Wk[(K0 + 2) * B + s] = 0.0


@njit(**JIT)
def _add_rows(n, dim, m, F, X):
    """4. (JVP) ``J^T dF`` (the backward pass's ``tau`` rows) plus ``P dq``."""
    for k in range(n):
        Fk, Xk = F[k * FROWS * B : (k + 1) * FROWS * B], X[3 * k * B : 3 * (k + 1) * B]
        for c in range(dim):
            for s in range(m):
                Fk[(O0 + c) * B + s] += Xk[c * B + s]


@njit(**JIT)
def _jvp_block(t, g, dim, q, qd, qdd, dq, dqd, dqdd, o, s0, m, S):
    n = t.shape[1]
    W, F, T, U, X = S[0], S[1], S[2], S[3], S[4]
    _primal(t, g, dim, q, qd, qdd, dq, dqd, dqdd, s0, m, S)
    _jvp_rods(t, dim, m, W, F, U, X)
    _tangent_start_points(t, dim, m, W, F)
    _backward(t, dim, m, W, F)
    _add_rows(n, dim, m, F, X)
    _rows_out(o, s0, m, n, dim, F, T)


@njit(**JIT)
def simd_jvp(p, q, qd, qdd, o, start, stop, S):
    """``dtau`` of samples ``start .. stop - 1`` of the flat ``(samples * dof,)`` states along the directions
    of ``p = (table, g, dim, dq, dqd, dqdd)`` into ``o``, :data:`B` at a time; ``S`` from :func:`scratch`
    (the signature of :func:`exo_bench.models.machine.simd_blocks.run`'s kernels)."""
    t, g, dim, dq, dqd, dqdd = p
    for s0 in range(start, stop, B):
        if stop - s0 >= B:  # a whole block: constant trip counts where LLVM inlines it (simd.py)
            _jvp_block(t, g, dim, q, qd, qdd, dq, dqd, dqdd, o, s0, B, S)
        else:
            _jvp_block(t, g, dim, q, qd, qdd, dq, dqd, dqdd, o, s0, stop - s0, S)


@njit(**JIT)
def _vjp_in(t, dim, m, W, F, U, X):
    """2. (VJP) per rod and lane: the force ``F_k`` into ``X``, ``J_k w_k`` over ``kappa_k``."""
    for k in range(t.shape[1]):
        Wk, Fk, Uk, Xk, s_k, zeta, eta = _link(t, k, W, F, U, X)
        for s in range(m):
            f = _forces(Fk, Wk, zeta, eta, s)
            cf, sf = Wk[CF * B + s], Wk[SF * B + s]
            if dim == 3:
                cp, sp, l = Wk[CP * B + s], Wk[SP * B + s], Wk[LEN * B + s]
                a = el.rod_acceleration_3d(cf, sf, cp, sp, l, 0.0, 0.0, 0.0, Uk[s], Uk[B + s], Uk[2 * B + s])  # J w
                for e in range(3):
                    Xk[e * B + s] = f[e]
                    Wk[(K0 + e) * B + s] = s_k * a[e]
            else:
                a2 = el.rod_acceleration_2d(cf, sf, Wk[LEN2 * B + s], 0.0, 0.0, Uk[s], Uk[B + s])  # J w
                Xk[s], Xk[B + s] = f[0], f[1]
                Wk[K0 * B + s], Wk[(K0 + 1) * B + s], Wk[(K0 + 2) * B + s] = s_k * a2[0], s_k * a2[1], 0.0


@njit(**JIT)
def _vjp_out(t, dim, m, W, F, U, X, G, H):
    """4. (VJP) per rod and lane, with ``v_k`` the force of the gravity-free passes: ``(A^q)^T v + P^T w``
    into ``F``'s result rows, ``(A^r)^T v`` into ``G``'s, ``J^T v`` into ``H``'s."""
    for k in range(t.shape[1]):
        Wk, Fk, Uk, Xk, s_k, zeta, eta = _link(t, k, W, F, U, X)
        Gk, Hk = G[k * FROWS * B : (k + 1) * FROWS * B], H[k * FROWS * B : (k + 1) * FROWS * B]
        for s in range(m):
            v0, v1, v2 = _forces(Fk, Wk, zeta, eta, s)
            cf, sf = Wk[CF * B + s], Wk[SF * B + s]
            if dim == 3:
                cp, sp = Wk[CP * B + s], Wk[SP * B + s]
                l, wr, vr, lr, wa, va, la = states_3d(Wk, s, B)
                aq = de.acceleration_by_q_3d(cf, sf, cp, sp, l, wr, vr, lr, wa, va, la)
                pq = de.projection_by_q_3d(cf, sf, cp, sp, l, Xk[s], Xk[B + s], Xk[2 * B + s])
                a = _transpose_apply_3d(aq, v0, v1, v2)
                b = _transpose_apply_3d(pq, Uk[s], Uk[B + s], Uk[2 * B + s])
                r = _transpose_apply_3d(de.acceleration_by_rates_3d(cf, sf, cp, sp, l, wr, vr, lr), v0, v1, v2)
                j = el.project_3d(cf, sf, cp, sp, l, v0, v1, v2)
                for e in range(3):
                    Fk[(O0 + e) * B + s] = s_k * (a[e] + b[e])
                    Gk[(O0 + e) * B + s] = s_k * r[e]
                    Hk[(O0 + e) * B + s] = s_k * j[e]
            else:
                l, wr, lr, wa, la = states_2d(Wk, s, B)
                a2 = _transpose_apply_2d(de.acceleration_by_q_2d(cf, sf, l, wr, lr, wa, la), v0, v1)
                b2 = _transpose_apply_2d(de.projection_by_q_2d(cf, sf, l, Xk[s], Xk[B + s]), Uk[s], Uk[B + s])
                r2 = _transpose_apply_2d(de.acceleration_by_rates_2d(cf, sf, l, wr, lr), v0, v1)
                j2 = el.project_2d(cf, sf, l, v0, v1)
                for e in range(2):
                    Fk[(O0 + e) * B + s] = s_k * (a2[e] + b2[e])
                    Gk[(O0 + e) * B + s] = s_k * r2[e]
                    Hk[(O0 + e) * B + s] = s_k * j2[e]


@njit(**JIT)
def _vjp_block(t, g, dim, q, qd, qdd, w, oq, oqd, om, s0, m, S):
    n = t.shape[1]
    W, F, T, U, X, G, H = S
    _primal(t, g, dim, q, qd, qdd, w, w, w, s0, m, S)
    _vjp_in(t, dim, m, W, F, U, X)
    _tangent_start_points(t, dim, m, W, F)
    _subtree_sums(t, m, W, F)
    _vjp_out(t, dim, m, W, F, U, X, G, H)
    _rows_out(oq, s0, m, n, dim, F, T)
    _rows_out(oqd, s0, m, n, dim, G, T)
    _rows_out(om, s0, m, n, dim, H, T)


@njit(**JIT)
def simd_vjp(p, q, qd, qdd, o, start, stop, S):
    """``(w^T dtau/dq, w^T dtau/dqd, w^T M)`` of samples ``start .. stop - 1`` into ``o = (oq, oqd, om)``
    (flat), ``p = (table, g, dim, w)``; as :func:`simd_jvp`."""
    t, g, dim, w = p
    oq, oqd, om = o
    for s0 in range(start, stop, B):
        if stop - s0 >= B:
            _vjp_block(t, g, dim, q, qd, qdd, w, oq, oqd, om, s0, B, S)
        else:
            _vjp_block(t, g, dim, q, qd, qdd, w, oq, oqd, om, s0, stop - s0, S)


@njit(**JIT)
def jvp_whole(t, g, dim, q, qd, qdd, dq, dqd, dqdd, o, start, W, F, T, U, X, G, H):
    """:func:`simd_jvp` of the samples from ``start`` of a ``(S, dof)`` batch in the calling thread, every
    argument an array or a number: numba's dispatcher types those in C (a tuple argument it types in Python,
    a few us a call). ``start`` comes from the caller (0): a constant here would be typed as a literal and
    compile :func:`simd_jvp` a second time, apart from the signature :func:`exo_bench.models.machine.simd_blocks.run` calls."""
    p = (t, g, dim, dq.reshape(dq.size), dqd.reshape(dqd.size), dqdd.reshape(dqdd.size))
    S = (W, F, T, U, X, G, H)
    simd_jvp(p, q.reshape(q.size), qd.reshape(qd.size), qdd.reshape(qdd.size), o.reshape(o.size), start, q.shape[0], S)


@njit(**JIT)
def vjp_whole(t, g, dim, q, qd, qdd, w, oq, oqd, om, start, W, F, T, U, X, G, H):
    """:func:`simd_vjp` of the samples from ``start`` of a batch in the calling thread (as :func:`jvp_whole`)."""
    o = (oq.reshape(oq.size), oqd.reshape(oqd.size), om.reshape(om.size))
    S = (W, F, T, U, X, G, H)
    simd_vjp((t, g, dim, w.reshape(w.size)), q.reshape(q.size), qd.reshape(qd.size), qdd.reshape(qdd.size), o,
             start, q.shape[0], S)  # fmt: skip


def _flat(*arrays: np.ndarray) -> tuple[np.ndarray, ...]:
    return tuple(a.reshape(-1) for a in arrays)


def jvp(table, dim: int, g: float, q, qd, qdd, dq, dqd, dqdd, scratch) -> np.ndarray:
    """``dtau (S, dof)`` of C-contiguous float64 ``(S, dof)`` arrays (the provider checks them), ``g`` a
    float and ``dim`` an int: :func:`jvp_whole` in the calling thread, or a large batch over threads by
    :func:`exo_bench.models.machine.simd_blocks.run`; ``scratch`` a :class:`exo_bench.models.machine.simd_blocks.ThreadScratch`
    of :func:`scratch`."""
    o = np.empty(q.shape)
    if q.shape[0] < parallel_min_samples(q.shape[1]):
        jvp_whole(table, g, dim, q, qd, qdd, dq, dqd, dqdd, o, 0, *scratch())
    else:
        x, xd, xdd, flat = _flat(q, qd, qdd, o)
        run(simd_jvp, (table, g, dim, *_flat(dq, dqd, dqdd)), x, xd, xdd, flat, q.shape[0], scratch=scratch)
    return o


def vjp(table, dim: int, g: float, q, qd, qdd, w, scratch) -> tuple[np.ndarray, ...]:
    """``(w^T dtau/dq, w^T dtau/dqd, w^T M)``, ``(S, dof)`` each (as :func:`jvp`)."""
    out = (np.empty(q.shape), np.empty(q.shape), np.empty(q.shape))
    if q.shape[0] < parallel_min_samples(q.shape[1]):
        vjp_whole(table, g, dim, q, qd, qdd, w, *out, 0, *scratch())
    else:
        x, xd, xdd = _flat(q, qd, qdd)
        run(simd_vjp, (table, g, dim, w.reshape(-1)), x, xd, xdd, _flat(*out), q.shape[0], scratch=scratch)
    return out
