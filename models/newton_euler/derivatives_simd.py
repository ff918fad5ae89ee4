"""The analytic derivatives of inverse dynamics, compiled to vectorise across samples: blocks of
:data:`~exo_bench.models.machine.simd_blocks.LANES` samples, each step a loop over the samples of a block that
LLVM turns into SIMD instructions (the algorithm: :mod:`exo_bench.models.newton_euler.derivatives`; the
per-sample kernel: :mod:`.derivatives_compiled`).

Per block, one driver for 2D and 3D (``dim`` chooses the forward pass):

1. **the passes** of newton-euler's batched kernel (:mod:`exo_bench.models.newton_euler.simd`, its
   blocks of :data:`~exo_bench.models.machine.simd_blocks.LANES`): the transpose in, the forward pass (its
   branch-free ``sin``/``cos``, libm beyond their range), and, after the start points' accelerations
   ``A`` are copied aside (the backward pass writes ``tau`` over them), the backward pass, which leaves
   the finished subtree sums ``D`` in the rows ``F0..F2``;
2. **per rod**, each sample a lane: ``F_k = eta A_k + zeta kappa_k + D_k`` recomputed bit for bit
   (:func:`exo_bench.models.mechanism.rod_elements.rod_force`) and the signed columns of
   :mod:`.derivative_elements` into ``Y`` (row ``r`` of link ``k`` at ``(r n + k) B``: the rows of
   :mod:`.derivatives_compiled`, one lane per sample) and ``P``;
3. **the blocks**, sample by sample: its lane of ``Y`` and ``P`` gathered (O(n)) into the layout of
   :mod:`.derivatives_compiled`, whose row loops (one vectorised loop of ``dof`` per output row) write
   the sample's contiguous ``(dof, dof)`` outputs. (Before: each entry for the ``B`` samples in one
   loop into a lane-major ``G``, then a transpose out of ``G``: exo5-3d 1.68 us per sample against
   ID's 0.168, 10.0x, at load 15-19; storing lane-major entries straight into the outputs was slower
   still, 3.6 us.)

Its sines and cosines are newton-euler's batched kernel's: it differs from the per-sample kernel
(libm's) by those only (:data:`~exo_bench.models.machine.fast_trig.ULPS` ulp each). Scratch per thread
(:func:`scratch`): the passes' ``(W, F, T)``, ``A (3 n B)``, ``Y (27 n B)``, ``P (9 n B)``,
``G (3 dof^2 B)``, of which step 3 uses ``39 n`` entries (173 kB at exo5-3d: the kernel is for small mechanisms; ``kernel="auto"`` takes the
per-sample kernel from :data:`exo_bench.models.newton_euler.derivatives.SIMD_BELOW_LINKS` links on).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.newton_euler import derivatives_compiled as dc
from exo_bench.models.newton_euler.derivatives_compiled import _blocks as _row_blocks
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.newton_euler import simd
from exo_bench.models.newton_euler.compiled import WIDTH
from exo_bench.models.machine.numba_cache import inline
from exo_bench.models.machine.numba_runtime import JIT, ensure
from exo_bench.models.machine.simd_blocks import states_2d, states_3d
from exo_bench.models.machine.simd_blocks import CF, CP, F0, FROWS, K0, LANES, O0, ROWS, SF, SP, block_transposes
from exo_bench.models.runtime.forward_check import _row_clear
from exo_bench.models.states.validation_pass import OK, QD, QDD, status

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
def _samples_out(mu, dim, m, s0, Y, P, G, om, oq, oqd):
    """3. Per sample of the block: its lane of ``Y`` and ``P`` gathered into the per-sample kernel's layout
    (O(n), in ``G``), and the blocks by that kernel's row loops straight into its contiguous outputs
    (:func:`exo_bench.models.newton_euler.derivatives_compiled._blocks`)."""
    n = mu.shape[0]
    dd = dim * dim
    Ys = G[: 27 * n].reshape((9, 3 * n))
    Ps = G[27 * n : 36 * n].reshape((9, n))
    row = G[36 * n : 39 * n]
    for s in range(m):
        for kind in range(3):
            for d in range(dim):
                for e in range(dim):
                    src = (kind * dd + d * dim + e) * n
                    for k in range(n):
                        Ys[kind * dim + e, d * n + k] = Y[(src + k) * B + s]
        for r in range(dd):
            for k in range(n):
                Ps[r, k] = P[(r * n + k) * B + s]
        _row_blocks(mu, dim, Ys, Ps, oq[s0 + s], oqd[s0 + s], om[s0 + s], row)


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
    _samples_out(mu, dim, m, s0, Y, P, G, om, oq, oqd)


@njit(**JIT)
def simd_derivatives(p, q, qd, qdd, o, start, stop, S):
    """Samples ``start .. stop - 1`` of the flat ``(samples * dof,)`` states into the ``(samples, dof,
    dof)`` outputs ``o = (dtau_dq, dtau_dqd, M)``, :data:`B` at a time; ``p = (table, mu, g, dim)``;
    ``S`` from :func:`scratch` (the signature of :func:`exo_bench.models.machine.simd_blocks.run`'s kernels)."""
    t, mu, g, dim = p
    oq, oqd, om = o
    for s0 in range(start, stop, B):
        if stop - s0 >= B:
            _block(t, mu, g, dim, q, qd, qdd, oq, oqd, om, s0, B, S)
        else:
            _block(t, mu, g, dim, q, qd, qdd, oq, oqd, om, s0, stop - s0, S)


# ---------------------------------------------------------------------- one sample of the public call
#: :func:`checked_one`'s answers where it wrote nothing (beside those of
#: :func:`exo_bench.models.newton_euler.derivatives_compiled._unsafe`, 1-4): a state not plain (strides other
#: than 8 bytes, or not aligned), or a check of ``check=True`` that did not clear the state. The caller's
#: exact path then refuses naming why, or decides (:class:`exo_bench.models.derivatives.Derivatives`).
NOT_PLAIN, EXACT = 5, 6
#: Floats of the head of :func:`one_workspace`: the ends of its parts.
_HEAD = 16


def one_workspace(table: np.ndarray, mu: np.ndarray, dim: int, fplan: np.ndarray, vplan: np.ndarray, simd: bool):
    """The packed first argument of :func:`checked_one`, one per thread: a head of the parts' ends, the table,
    ``mu``, the plans of the checks (``fplan``: :mod:`exo_bench.models.runtime.forward_check`'s; ``vplan``:
    :mod:`exo_bench.models.states.validation_pass`'s int64, as float64 bits) and the scratch of the kernel that
    runs (``simd``: :func:`scratch`'s, else :func:`exo_bench.models.newton_euler.derivatives_compiled.scratch`'s),
    each flat: each array argument of a compiled entry costs its unboxing (~40 ns)."""
    n = table.shape[1]
    kernel = scratch(n, dim) if simd else dc.scratch(n, dim)
    parts = [table, mu, fplan, vplan.view(np.float64), *(a.view(np.float64) for a in kernel)]
    ends = np.cumsum([a.size for a in parts]) + _HEAD
    head = np.zeros(_HEAD)
    head[: len(ends)] = ends
    return np.concatenate([head, *(a.reshape(-1) for a in parts)])


#: The entry's options: :data:`JIT` without numba's reference-counted memory, so that unboxing an array
#: allocates nothing (as :mod:`exo_bench.models.states.validation_pass`'s entries: about half the cost of a call's
#: seven arrays); nothing it runs allocates.
_LEAN: Any = {**JIT, "_nrt": False}  # Any: numba's stubs do not list _nrt


@njit(**_LEAN)
def checked_one(ws, n, g, dim, simd, check, x, xd, xdd, oq, oqd, om):
    """The compiled per-sample entry of ``model.derivatives.inverse_dynamics`` on a :func:`one_workspace`:
    the states plain (else :data:`NOT_PLAIN`) and their and the outputs' shapes and overlaps
    (:func:`exo_bench.models.newton_euler.derivatives_compiled._unsafe`), then with ``check`` the states'
    validation pass (:func:`exo_bench.models.states.validation_pass.status`) and the clearance of the singular
    states (:func:`exo_bench.models.runtime.forward_check._row_clear`) (else :data:`EXACT`), then the kernel that a
    batch of this mechanism runs (``simd``: :func:`_block` on one lane, else the per-sample
    :func:`exo_bench.models.newton_euler.derivatives_compiled.derivatives_sample`), so that one sample has the
    bits of its row in a batch: 0 when written. One call, an int back (an array returned would cost its
    boxing, ~0.4 us)."""
    if not (dc._plain(x) and dc._plain(xd) and dc._plain(xdd)):
        return NOT_PLAIN
    code = dc._unsafe(n, dim, x, xd, xdd, oq, oqd, om)
    if code:
        return code
    dof = dim * n
    e0, e1, e2, e3, e4, e5 = int(ws[0]), int(ws[1]), int(ws[2]), int(ws[3]), int(ws[4]), int(ws[5])
    e6, e7, e8, e9, e10 = int(ws[6]), int(ws[7]), int(ws[8]), int(ws[9]), int(ws[10])  # the parts' ends
    if check:
        if status(x, xd, xdd, QD | QDD, ws[e2:e3].view(np.int64)) != OK:
            return EXACT
        if not _row_clear(x, 0, dof, n, ws[e1:e2]):
            return EXACT
    t, mu = ws[_HEAD:e0].reshape((8, n)), ws[e0:e1].reshape((n, n))
    if simd:
        S = (ws[e3:e4], ws[e4:e5], ws[e5:e6].view(np.int64), ws[e6:e7], ws[e7:e8], ws[e8:e9], ws[e9:e10])
        one = (1, dof, dof)
        _block(t, mu, g, dim, x, xd, xdd, oq.reshape(one), oqd.reshape(one), om.reshape(one), 0, 1, S)
    else:
        W, Y, P = ws[e3:e4].reshape((n, WIDTH)), ws[e4:e5].reshape((9, 3 * n)), ws[e5:e6].reshape((9, n))
        m = ws[e7:e8]
        dc.derivatives_sample(t, mu, g, dim, x, xd, xdd, oq, oqd, om, W, Y, P, ws[e6:e7], m, m, False)
    return 0
