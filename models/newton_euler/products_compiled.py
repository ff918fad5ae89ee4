"""Directional derivatives of inverse dynamics, compiled (numba): the formulas of
:mod:`exo_bench.models.newton_euler.products` per sample, and threads over samples for batches.

Per sample, O(n) and no ``n x n`` array:

1. newton-euler's own passes (:func:`exo_bench.models.newton_euler.compiled._inverse_sample`) and the per-rod
   signed columns ``J_k``, ``A^q_k``, ``A^r_k`` and ``P_k`` (:func:`.derivatives_compiled._columns`, the
   rod elements' derivatives: nothing physical written twice);
2. per rod the change of its acceleration (JVP: ``A^q dq + A^r dqd + J dqdd``) or ``J w`` (VJP);
3. the gravity-free passes on it (:func:`_passes`: the forward pass of start-point accelerations and the
   backward pass of subtree sums, :func:`exo_bench.models.rod_elements.rod_force` and ``subtree_share``,
   as :func:`exo_bench.models.newton_euler.passes.rod_forces` at ``g = 0``): ``(mu (x) I)`` applied in O(n);
4. per rod ``J^T dF + P dq`` (JVP) or ``(A^q)^T v + P^T w``, ``(A^r)^T v``, ``J^T v`` (VJP).

Work per sample: about two inverse dynamics (the passes twice) and the per-rod columns.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from exo_bench.models import rod_elements as el
from exo_bench.models.newton_euler.compiled import _ETA, _PARENT, _THETA, _ZETA, WIDTH, _inverse_sample
from exo_bench.models.newton_euler import products
from exo_bench.models.newton_euler.derivatives_compiled import _columns
from exo_bench.models.numba_runtime import JIT, SAMPLES_PER_TASK, run

_J, _AQ, _AR = 0, 1, 2  # kinds of the rows of Y (derivatives_compiled's layout)


@njit(**JIT)
def _passes(t, dim, V):
    """``V[k, 0:3]`` (each rod's acceleration) -> ``V[k, 6:9]``, the forces ``(mu (x) I) V`` of the
    gravity-free passes (``V[k, 3:6]``: start-point accelerations; ``V[k, 9:12]``: subtree sums)."""
    n = t.shape[1]
    for k in range(n):  # roots first
        p = int(t[_PARENT, k])
        for e in range(3):
            V[k, 3 + e] = V[p, 3 + e] + V[p, e] if p >= 0 else 0.0
            V[k, 9 + e] = 0.0
    for k in range(n - 1, -1, -1):  # leaves first
        zeta, eta, theta = t[_ZETA, k], t[_ETA, k], t[_THETA, k]
        p = int(t[_PARENT, k])
        for e in range(dim):
            V[k, 6 + e] = el.rod_force(zeta, eta, V[k, 3 + e], V[k, e], V[k, 9 + e])
            if p >= 0:
                V[p, 9 + e] += el.subtree_share(theta, eta, V[k, 3 + e], V[k, e], V[k, 9 + e])


@njit(**JIT)
def _apply(Y, kind, dim, n, k, v):
    """Component ``e`` of rod ``k``'s ``kind`` matrix times its coordinates of ``v``, for e = 0, 1, 2."""
    r = kind * dim
    a0 = a1 = a2 = 0.0
    for d in range(dim):
        x = v[d * n + k]
        a0 += Y[r, d * n + k] * x
        a1 += Y[r + 1, d * n + k] * x
        if dim == 3:
            a2 += Y[r + 2, d * n + k] * x
    return a0, a1, a2


@njit(**JIT)
def _transpose_apply(Y, kind, dim, n, k, c, V, at):
    """Row ``c`` of rod ``k``'s ``kind`` matrix transposed, times ``V[k, at:at + dim]``."""
    r, col = kind * dim, c * n + k
    a = 0.0
    for e in range(dim):
        a += Y[r + e, col] * V[k, at + e]
    return a


@njit(**JIT)
def _diagonal(P, dim, n, k, c, v, transpose):
    """Row ``c`` of rod ``k``'s ``P_k`` (of ``P_k^T`` with ``transpose``) times its coordinates of ``v``;
    entry ``(c, d)`` of ``P_k`` is ``P[d dim + c, k]``."""
    a = 0.0
    for d in range(dim):
        a += (P[c * dim + d, k] if transpose else P[d * dim + c, k]) * v[d * n + k]
    return a


@njit(**JIT)
def _prepare(t, g, dim, x, xd, xdd, W, Y, P, tau):
    """1. The passes and the per-rod columns of one sample."""
    _inverse_sample(t, g, dim, x, xd, xdd, tau, 0, W)
    _columns(t, dim, x, xd, xdd, W, Y, P)


@njit(**JIT)
def jvp_sample(t, g, dim, x, xd, xdd, dx, dxd, dxdd, o, W, Y, P, tau, V):
    """``o = dtau`` of one sample along ``(dx, dxd, dxdd)`` (module docstring)."""
    n = t.shape[1]
    _prepare(t, g, dim, x, xd, xdd, W, Y, P, tau)
    for k in range(n):
        a0, a1, a2 = _apply(Y, _AQ, dim, n, k, dx)
        b0, b1, b2 = _apply(Y, _AR, dim, n, k, dxd)
        c0, c1, c2 = _apply(Y, _J, dim, n, k, dxdd)
        V[k, 0], V[k, 1], V[k, 2] = a0 + b0 + c0, a1 + b1 + c1, a2 + b2 + c2
    _passes(t, dim, V)
    for k in range(n):
        for c in range(dim):
            o[c * n + k] = _transpose_apply(Y, _J, dim, n, k, c, V, 6) + _diagonal(P, dim, n, k, c, dx, False)


@njit(**JIT)
def vjp_sample(t, g, dim, x, xd, xdd, w, oq, oqd, om, W, Y, P, tau, V):
    """``(w^T dtau/dq, w^T dtau/dqd, w^T M)`` of one sample (module docstring)."""
    n = t.shape[1]
    _prepare(t, g, dim, x, xd, xdd, W, Y, P, tau)
    for k in range(n):
        V[k, 0], V[k, 1], V[k, 2] = _apply(Y, _J, dim, n, k, w)
    _passes(t, dim, V)
    for k in range(n):
        for d in range(dim):
            oq[d * n + k] = _transpose_apply(Y, _AQ, dim, n, k, d, V, 6) + _diagonal(P, dim, n, k, d, w, True)
            oqd[d * n + k] = _transpose_apply(Y, _AR, dim, n, k, d, V, 6)
            om[d * n + k] = _transpose_apply(Y, _J, dim, n, k, d, V, 6)


@njit(**JIT)
def _range(t, g, dim, q, qd, qdd, u, v, z, o, p, r, reverse, start, stop):
    """Samples ``start .. stop - 1``: the VJP of ``w = u`` into ``(o, p, r)`` (``reverse``), else the JVP along
    ``(u, v, z)`` into ``o`` (scratch once)."""
    n = t.shape[1]
    W, Y, P, tau = np.zeros((n, WIDTH)), np.zeros((9, 3 * n)), np.zeros((9, n)), np.zeros(dim * n)
    V = np.zeros((n, 12))
    for s in range(start, stop):
        if reverse:
            vjp_sample(t, g, dim, q[s], qd[s], qdd[s], u[s], o[s], p[s], r[s], W, Y, P, tau, V)
        else:
            jvp_sample(t, g, dim, q[s], qd[s], qdd[s], u[s], v[s], z[s], o[s], W, Y, P, tau, V)


@njit(**JIT)
def products_serial(t, g, dim, q, qd, qdd, u, v, z, o, p, r, reverse):
    """Every sample of ``(S, dof)`` arrays in turn (:func:`_range`)."""
    _range(t, g, dim, q, qd, qdd, u, v, z, o, p, r, reverse, 0, q.shape[0])


@njit(parallel=True, **JIT)
def products_parallel(t, g, dim, q, qd, qdd, u, v, z, o, p, r, reverse):
    """:func:`products_serial` in blocks of :data:`exo_bench.models.numba_runtime.SAMPLES_PER_TASK` over numba's threads."""
    S = q.shape[0]
    for b in prange((S + SAMPLES_PER_TASK - 1) // SAMPLES_PER_TASK):
        stop = min(S, (b + 1) * SAMPLES_PER_TASK)
        _range(t, g, dim, q, qd, qdd, u, v, z, o, p, r, reverse, b * SAMPLES_PER_TASK, stop)


def jvp(tree, table, dim: int, g: float, q, qd, qdd, dq, dqd, dqdd, reference: bool = False) -> np.ndarray:
    """``dtau (S, dof)`` of C-contiguous float64 ``(S, dof)`` arrays (the provider checks them); with
    ``reference`` the numpy reference (:func:`exo_bench.models.newton_euler.products.inverse_jvp`)."""
    if reference:
        return products.inverse_jvp(tree, dim, g, q, qd, qdd, dq, dqd, dqdd)
    o = np.empty(q.shape)
    run(products_serial, products_parallel, (table, g, dim, q, qd, qdd, dq, dqd, dqdd, o, o, o, False), q.shape[0])
    return o


def vjp(tree, table, dim: int, g: float, q, qd, qdd, w, reference: bool = False) -> tuple[np.ndarray, ...]:
    """``(w^T dtau/dq, w^T dtau/dqd, w^T M)``, ``(S, dof)`` each (as :func:`jvp`;
    :func:`exo_bench.models.newton_euler.products.inverse_vjp`)."""
    if reference:
        return products.inverse_vjp(tree, dim, g, q, qd, qdd, w)
    out = (np.empty(q.shape), np.empty(q.shape), np.empty(q.shape))
    run(products_serial, products_parallel, (table, g, dim, q, qd, qdd, w, w, w, *out, True), q.shape[0])
    return out
