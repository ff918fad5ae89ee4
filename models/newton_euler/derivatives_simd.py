"""The analytic derivatives of inverse dynamics, compiled to vectorise across samples: blocks of
:data:`~exo_bench.models.simd_blocks.LANES` samples, each step a loop over the samples of a block that
LLVM turns into SIMD instructions (the algorithm: :mod:`exo_bench.models.newton_euler.derivatives`; the
per-sample kernel: :mod:`.derivatives_compiled`).

Per block, one driver for 2D and 3D (``dim`` chooses the forward pass):

1. **the passes** of newton-euler's batched kernel (:mod:`exo_bench.models.newton_euler.simd`, its
   blocks of :data:`~exo_bench.models.simd_blocks.LANES`): the transpose in, the forward pass (its
   branch-free ``sin``/``cos``, libm beyond their range), and, after the start points' accelerations
   ``A`` are copied aside (the backward pass writes ``tau`` over them), the backward pass, which leaves
   the finished subtree sums ``D`` in the rows ``F0..F2``;
2. **per rod**, each sample a lane: ``F_k = eta A_k + zeta kappa_k + D_k`` recomputed bit for bit
   (:func:`exo_bench.models.rod_elements.rod_force`) and the signed columns of
   :mod:`.derivative_elements` into ``Y`` (row ``r`` of link ``k`` at ``(r n + k) B``: the rows of
   :mod:`.derivatives_compiled`, one lane per sample) and ``P``;
3. **the blocks** ``mu_ij J_i^T Y_j``, each output entry for the ``B`` samples of the block in one
   vectorised loop into ``G`` (lane-major: entry ``e`` of sample ``s`` at ``e B + s``), then ``P`` on
   the diagonal;
4. **transpose out**: each sample's entries from ``G`` into its contiguous ``(dof, dof)`` outputs.
   (Storing straight into the outputs, at the stride of one sample's ``3 dof^2`` entries, took 3.6
   and 180 us per sample on exo5-3d and a 3D chain of 20 against 3.3 and 19 for the per-sample
   kernel, the shared machine at load 6-9.)

Its sines and cosines are newton-euler's batched kernel's: it differs from the per-sample kernel
(libm's) by those only (:data:`~exo_bench.models.fast_trig.ULPS` ulp each). Scratch per thread
(:func:`scratch`): the passes' ``(W, F, T)``, ``A (3 n B)``, ``Y (27 n B)``, ``P (9 n B)``,
``G (3 dof^2 B)`` (173 kB at exo5-3d: the kernel is for small mechanisms; ``kernel="auto"`` takes the
per-sample kernel from :data:`exo_bench.models.newton_euler.derivatives.SIMD_BELOW_LINKS` links on).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models import rod_elements as el
from exo_bench.models.newton_euler import simd
from exo_bench.models.numba_cache import inline
from exo_bench.models.numba_runtime import JIT, ensure
from exo_bench.models.simd_angles import states_2d, states_3d
from exo_bench.models.simd_blocks import CF, CP, F0, FROWS, K0, LANES, O0, ROWS, SF, SP, block_transposes

ensure()
inline(de.DERIVATIVE_ELEMENTS, de.__file__.rsplit("/", 1)[0])

B = LANES
_SIGN, _ZETA, _ETA = 1, 2, 3
_scratch_passes, _rows_in, _ = block_transposes(LANES)
_forward_2d, _forward_3d, _backward = simd._WIDE._forward_2d, simd._WIDE._forward_3d, simd._WIDE._backward


def scratch(n: int, dim: int):
    """One thread's scratch of :func:`simd_derivatives`: the passes' ``(W, F, T)``, then ``A, Y, P``."""
    W, F, T = _scratch_passes(n, dim)
    dof = dim * n
    return W, F, T, np.zeros(3 * n * B), np.zeros(27 * n * B), np.zeros(9 * n * B), np.zeros(3 * dof * dof * B)


@njit(**JIT)
def _save_start_points(n, m, F, A):
    """1. (end of the forward pass) ``A_k``, rows ``O0..O2`` of ``F``, into ``A`` (``(c n + k) B``)."""
    for k in range(n):
        for c in range(3):
            src, dst = (k * FROWS + O0 + c) * B, (c * n + k) * B
            for s in range(m):
                A[dst + s] = F[src + s]


@njit(**JIT)
def _columns(t, dim, m, W, F, A, Y, P):
    """2. Per rod and lane: ``F_k``, the signed columns into ``Y`` and ``s_k d(J_k^T F_k)/dq_k`` into ``P``."""
    n = t.shape[1]
    for k in range(n):
        s_k, zeta, eta = t[_SIGN, k], t[_ZETA, k], t[_ETA, k]
        w, f = k * ROWS * B, k * FROWS * B
        for s in range(m):
            a = w + s
            f0 = el.rod_force(zeta, eta, A[k * B + s], W[a + K0 * B], F[f + F0 * B + s])
            f1 = el.rod_force(zeta, eta, A[(n + k) * B + s], W[a + (K0 + 1) * B], F[f + (F0 + 1) * B + s])
            cf, sf = W[a + CF * B], W[a + SF * B]
            if dim == 2:
                l, wr, lr, wa, la = states_2d(W, a, B)
                jac = de.jacobian_2d(cf, sf, l)
                aq = de.acceleration_by_q_2d(cf, sf, l, wr, lr, wa, la)
                ar = de.acceleration_by_rates_2d(cf, sf, l, wr, lr)
                pq = de.projection_by_q_2d(cf, sf, l, f0, f1)
                for r in range(4):
                    Y[(r * n + k) * B + s] = s_k * jac[r]
                    Y[((4 + r) * n + k) * B + s] = s_k * aq[r]
                    Y[((8 + r) * n + k) * B + s] = s_k * ar[r]
                    P[(r * n + k) * B + s] = s_k * pq[r]
            else:
                f2 = el.rod_force(zeta, eta, A[(2 * n + k) * B + s], W[a + (K0 + 2) * B], F[f + (F0 + 2) * B + s])
                cp, sp = W[a + CP * B], W[a + SP * B]
                l, wr, vr, lr, wa, va, la = states_3d(W, a, B)
                jac = de.jacobian_3d(cf, sf, cp, sp, l)
                aq = de.acceleration_by_q_3d(cf, sf, cp, sp, l, wr, vr, lr, wa, va, la)
                ar = de.acceleration_by_rates_3d(cf, sf, cp, sp, l, wr, vr, lr)
                pq = de.projection_by_q_3d(cf, sf, cp, sp, l, f0, f1, f2)
                for r in range(9):
                    Y[(r * n + k) * B + s] = s_k * jac[r]
                    Y[((9 + r) * n + k) * B + s] = s_k * aq[r]
                    Y[((18 + r) * n + k) * B + s] = s_k * ar[r]
                    P[(r * n + k) * B + s] = s_k * pq[r]


@njit(**JIT)
def _blocks(mu, dim, m, Y, P, G):
    """3. Every block ``mu_ij J_i^T Y_j`` of ``m`` lanes into ``G`` (entry ``e = (kind dof + row) dof +
    column`` at ``e B``, kinds ``M, dtau_dq, dtau_dqd``), then ``P`` on the diagonal of ``dtau_dq``."""
    n = mu.shape[0]
    dd, dof = dim * dim, dim * n
    for i in range(n):
        for c in range(dim):
            z = Y[(c * dim * n + i) * B :]  # row c of s_i J_i^T: component e at (e n) B
            r = c * n + i
            for kind in range(3):
                for d in range(dim):
                    y = Y[(kind * dd + d * dim) * n * B :]
                    for j in range(n):
                        mij, at = mu[i, j], j * B
                        g = G[((kind * dof + r) * dof + d * n + j) * B :]
                        if dim == 3:
                            for s in range(m):
                                g[s] = mij * (
                                    z[s] * y[at + s]
                                    + z[n * B + s] * y[(n + j) * B + s]
                                    + z[2 * n * B + s] * y[(2 * n + j) * B + s]
                                )
                        else:
                            for s in range(m):
                                g[s] = mij * (z[s] * y[at + s] + z[n * B + s] * y[(n + j) * B + s])
        for c in range(dim):
            for d in range(dim):
                p, g = ((d * dim + c) * n + i) * B, G[((dof + c * n + i) * dof + d * n + i) * B :]
                for s in range(m):
                    g[s] += P[p + s]


@njit(**JIT)
def _rows_out(dof, s0, m, G, om, oq, oqd):
    """4. The lanes of ``G`` into samples ``s0 .. s0 + m - 1`` of the three outputs (contiguous rows)."""
    E = dof * dof
    for s in range(m):
        for kind in range(3):
            o = (om if kind == 0 else (oq if kind == 1 else oqd))[s0 + s].reshape(E)
            g = G[kind * E * B + s :]
            for e in range(E):
                o[e] = g[e * B]


@njit(**JIT)
def _block(t, mu, g, dim, q, qd, qdd, oq, oqd, om, s0, m, S):
    """1-3 for the ``m`` samples from ``s0``."""
    n = t.shape[1]
    W, F, T, A, Y, P, G = S
    _rows_in(q, qd, qdd, s0, m, n, dim, W, T)
    lo = hi = 0  # no prefetch of the next block: its states are a small share of the traffic here
    if dim == 3:
        _forward_3d(t, g, m, W, F, q, qd, qdd, q, lo, hi)
    else:
        _forward_2d(t, g, m, W, F, q, qd, qdd, q, lo, hi)
    _save_start_points(n, m, F, A)
    _backward(t, dim, m, W, F)
    _columns(t, dim, m, W, F, A, Y, P)
    _blocks(mu, dim, m, Y, P, G)
    _rows_out(dim * n, s0, m, G, om, oq, oqd)


@njit(**JIT)
def simd_derivatives(p, q, qd, qdd, o, start, stop, S):
    """Samples ``start .. stop - 1`` of the flat ``(samples * dof,)`` states into the ``(samples, dof,
    dof)`` outputs ``o = (dtau_dq, dtau_dqd, M)``, :data:`B` at a time; ``p = (table, mu, g, dim)``;
    ``S`` from :func:`scratch` (the signature of :func:`exo_bench.models.simd_blocks.run`'s kernels)."""
    t, mu, g, dim = p
    oq, oqd, om = o
    for s0 in range(start, stop, B):
        if stop - s0 >= B:
            _block(t, mu, g, dim, q, qd, qdd, oq, oqd, om, s0, B, S)
        else:
            _block(t, mu, g, dim, q, qd, qdd, oq, oqd, om, s0, stop - s0, S)
