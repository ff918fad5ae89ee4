"""Directional derivatives of inverse dynamics (JVP, VJP) through the Newton-Euler passes, O(n) per sample:
the numpy reference and the per-sample compiled kernels of one algorithm (the SIMD form: :mod:`.products_simd`).

``tau = J^T F`` per rod (``J = blockdiag(s_i J_i(q_i))``) with the force ``F = (mu (x) I) kappa + g_r`` of
the two passes and each rod's acceleration ``kappa_i = s_i (J_i qdd_i + J_i' qd_i)``. With the per-rod
columns of :func:`exo_bench.models.newton_euler.derivatives.rod_columns` (``J_i``, ``A^q_i = d kappa_i
/d q_i``, ``A^r_i = d kappa_i/d qd_i``, ``P_i = s_i d(J_i^T F_i)/d q_i`` at fixed ``F``, each ``dim x
dim``)::

    dtau/dq = blockdiag(P) + J^T (mu (x) I) A^q,   dtau/dqd = J^T (mu (x) I) A^r,   M = J^T (mu (x) I) J.

* **Forward mode** (:func:`inverse_jvp`): the rods' acceleration changes ``A^q dq + A^r dqd + J dqdd``,
  the passes without gravity (``(mu (x) I)`` times them: :func:`exo_bench.models.newton_euler.passes.rod_forces`
  at ``g = 0``), then ``J^T`` and the diagonal term ``P dq``.
* **Reverse mode** (:func:`inverse_vjp`): ``v = (mu (x) I) J w`` by the same passes (``mu`` is symmetric),
  then per rod ``w^T dtau/dq_i = v_i^T A^q_i + w_i^T P_i``, ``w^T dtau/dqd_i = v_i^T A^r_i``, ``w^T M_i =
  v_i^T J_i``.

Both are one pass of the inverse dynamics plus one gravity-free pass and O(dim^2) per rod: no ``n x n``
array. Arrays are batch-first ``(S, dof)`` in block order ``[phi..., psi..., l...]``.

**Compiled (numba)**: the formulas above per sample, and threads over samples for batches.

Per sample, O(n) and no ``n x n`` array:

1. newton-euler's own passes (:func:`exo_bench.models.newton_euler.compiled._inverse_sample`) and the per-rod
   signed columns ``J_k``, ``A^q_k``, ``A^r_k`` and ``P_k`` (:func:`exo_bench.models.newton_euler.derivatives_compiled._columns`, the
   rod elements' derivatives: nothing physical written twice);
2. per rod the change of its acceleration (JVP: ``A^q dq + A^r dqd + J dqdd``) or ``J w`` (VJP);
3. the gravity-free passes on it (:func:`_passes`: the forward pass of start-point accelerations and the
   backward pass of subtree sums, :func:`exo_bench.models.mechanism.rod_elements.rod_force` and ``subtree_share``,
   as :func:`exo_bench.models.newton_euler.passes.rod_forces` at ``g = 0``): ``(mu (x) I)`` applied in O(n);
4. per rod ``J^T dF + P dq`` (JVP) or ``(A^q)^T v + P^T w``, ``(A^r)^T v``, ``J^T v`` (VJP).

Work per sample: about two inverse dynamics (the passes twice) and the per-rod columns.
"""

from __future__ import annotations

import numpy as np
from exo_bench.models.machine.numba_runtime import JIT, SAMPLES_PER_TASK, run
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.compiled import _ETA, _PARENT, _THETA, _ZETA, WIDTH, _inverse_sample
from exo_bench.models.newton_euler.derivatives_compiled import _columns
from exo_bench.models.newton_euler.derivatives import rod_columns
from exo_bench.models.newton_euler.passes import Tree
from numba import njit, prange


def _rods(x: np.ndarray, n: int, dim: int) -> np.ndarray:
    """``(S, dof)`` in block order as ``(n, dim, S)`` ``[link, coordinate, sample]``."""
    return np.transpose(x.T.reshape(dim, n, -1), (1, 0, 2))


def _flat(x: np.ndarray) -> np.ndarray:
    """``(n, dim, S)`` back to ``(S, dof)`` in block order."""
    return np.transpose(x, (1, 0, 2)).reshape(-1, x.shape[2]).T


def _apply(Y: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per rod ``Y_i v_i`` for columns ``Y (n, dim, dim, S)`` and ``v (n, dim, S)``."""
    return np.einsum("ieas,ias->ies", Y, v)


def _transpose_apply(Y: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Per rod ``Y_i^T v_i``."""
    return np.einsum("ieas,ies->ias", Y, v)


def inverse_jvp(tree: Tree, dim: int, g: float, q, qd, qdd, dq, dqd, dqdd) -> np.ndarray:
    """``dtau (S, dof)``: the derivative of inverse dynamics along ``(dq, dqd, dqdd)`` (module docstring)."""
    n = tree.parent.shape[0]
    J, Aq, Ar, P = rod_columns(tree, dim, g, q, qd, qdd)
    dQ = _rods(dq, n, dim)
    change = _apply(Aq, dQ) + _apply(Ar, _rods(dqd, n, dim)) + _apply(J, _rods(dqdd, n, dim))
    dF = passes.rod_forces(tree, dim, 0.0, change)
    return _flat(_transpose_apply(J, dF) + _apply(P, dQ))


def inverse_vjp(tree: Tree, dim: int, g: float, q, qd, qdd, w) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(w^T dtau/dq, w^T dtau/dqd, w^T M)``, ``(S, dof)`` each (module docstring)."""
    n = tree.parent.shape[0]
    J, Aq, Ar, P = rod_columns(tree, dim, g, q, qd, qdd)
    W = _rods(w, n, dim)
    v = passes.rod_forces(tree, dim, 0.0, _apply(J, W))
    return (
        _flat(_transpose_apply(Aq, v) + _transpose_apply(P, W)),
        _flat(_transpose_apply(Ar, v)),
        _flat(_transpose_apply(J, v)),
    )


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
def _prepare(t, g, dim, x, xd, xdd, W, Y, P, tau):
    """1. The passes and the per-rod columns of one sample."""
    _inverse_sample(t, g, dim, x, xd, xdd, tau, 0, W)
    _columns(t, dim, x, xd, xdd, W, Y, P)


@njit(**JIT)
def jvp_sample(t, g, dim, x, xd, xdd, dx, dxd, dxdd, o, W, Y, P, tau, V):
    """``o = dtau`` of one sample along ``(dx, dxd, dxdd)`` (module docstring)."""
    n = t.shape[1]
    _prepare(t, g, dim, x, xd, xdd, W, Y, P, tau)
    for k in range(n):  # the change of rod k's acceleration, A^q dq + A^r dqd + J dqdd
        V[k, 2] = 0.0  # in 2D
        for e in range(dim):
            a = b = c = 0.0
            for d in range(dim):
                col = d * n + k
                a += Y[_AQ * dim + e, col] * dx[col]
                b += Y[_AR * dim + e, col] * dxd[col]
                c += Y[_J * dim + e, col] * dxdd[col]
            V[k, e] = a + b + c
    _passes(t, dim, V)
    for k in range(n):  # written out, no helper: with helpers this loop took 4x its time (exo5-3d)
        for c in range(dim):
            col = c * n + k
            a = 0.0
            for e in range(dim):  # row c of J_k^T dF_k
                a += Y[_J * dim + e, col] * V[k, 6 + e]
            b = 0.0
            for d in range(dim):  # row c of P_k dq_k; entry (c, d) of P_k is P[d dim + c, k]
                b += P[d * dim + c, k] * dx[d * n + k]
            o[col] = a + b


@njit(**JIT)
def vjp_sample(t, g, dim, x, xd, xdd, w, oq, oqd, om, W, Y, P, tau, V):
    """``(w^T dtau/dq, w^T dtau/dqd, w^T M)`` of one sample (module docstring)."""
    n = t.shape[1]
    _prepare(t, g, dim, x, xd, xdd, W, Y, P, tau)
    for k in range(n):  # J_k w_k
        V[k, 2] = 0.0  # in 2D
        for e in range(dim):
            a = 0.0
            for d in range(dim):
                a += Y[_J * dim + e, d * n + k] * w[d * n + k]
            V[k, e] = a
    _passes(t, dim, V)
    for k in range(n):  # written out, as in jvp_sample
        for d in range(dim):
            col = d * n + k
            aq = ar = am = 0.0
            for e in range(dim):  # row d of (A^q_k)^T v_k, (A^r_k)^T v_k and J_k^T v_k
                x = V[k, 6 + e]
                aq += Y[_AQ * dim + e, col] * x
                ar += Y[_AR * dim + e, col] * x
                am += Y[_J * dim + e, col] * x
            b = 0.0
            for c in range(dim):  # row d of P_k^T w_k
                b += P[d * dim + c, k] * w[c * n + k]
            oq[col], oqd[col], om[col] = aq + b, ar, am


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
    """:func:`products_serial` in blocks of :data:`exo_bench.models.machine.numba_runtime.SAMPLES_PER_TASK` over numba's threads."""
    S = q.shape[0]
    for b in prange((S + SAMPLES_PER_TASK - 1) // SAMPLES_PER_TASK):
        stop = min(S, (b + 1) * SAMPLES_PER_TASK)
        _range(t, g, dim, q, qd, qdd, u, v, z, o, p, r, reverse, b * SAMPLES_PER_TASK, stop)


def jvp(tree, table, dim: int, g: float, q, qd, qdd, dq, dqd, dqdd, reference: bool = False) -> np.ndarray:
    """``dtau (S, dof)`` of C-contiguous float64 ``(S, dof)`` arrays (the provider checks them); with
    ``reference`` the numpy reference (:func:`exo_bench.models.newton_euler.products.inverse_jvp`)."""
    if reference:
        return inverse_jvp(tree, dim, g, q, qd, qdd, dq, dqd, dqdd)
    o = np.empty(q.shape)
    run(products_serial, products_parallel, (table, g, dim, q, qd, qdd, dq, dqd, dqdd, o, o, o, False), q.shape[0])
    return o


def vjp(tree, table, dim: int, g: float, q, qd, qdd, w, reference: bool = False) -> tuple[np.ndarray, ...]:
    """``(w^T dtau/dq, w^T dtau/dqd, w^T M)``, ``(S, dof)`` each (as :func:`jvp`;
    :func:`exo_bench.models.newton_euler.products.inverse_vjp`)."""
    if reference:
        return inverse_vjp(tree, dim, g, q, qd, qdd, w)
    out = (np.empty(q.shape), np.empty(q.shape), np.empty(q.shape))
    run(products_serial, products_parallel, (table, g, dim, q, qd, qdd, w, w, w, *out, True), q.shape[0])
    return out
