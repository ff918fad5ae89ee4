"""The Newton-Euler method, compiled (numba): the same passes as :mod:`models.newton_euler.passes`,
as loops over the links of one sample.

Per sample the kernels call the very element functions of :mod:`models.newton_euler.elements`
(registered with ``register_jitable``), so nothing physical is written twice; tests/test_newton_euler.py
holds them to the numpy reference. The layout follows the matrix family
(:mod:`matrix_method.compiled`): flat C-ordered ``(samples * dof,)`` states and result, a serial
driver, and a parallel driver over blocks of :data:`models.numba_threads.BLOCK` samples for large
batches (:func:`models.numba_threads.run`). The per-mechanism numbers come as one ``(8, n)`` table
(:meth:`models.newton_euler.tree.Tree.table`) and ``g``.

Per sample: ``2n`` (2D) or ``4n`` (3D) sines and cosines and O(n) arithmetic, for inverse and
forward dynamics alike.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numba.extending import register_jitable

from exo_bench.models.newton_euler import elements as el
from exo_bench.models.numba_threads import BLOCK, JIT

for _f in el.ELEMENTS:
    register_jitable(_f)

_PARENT, _SIGN, _ZETA, _ETA, _THETA, _NU, _PIVOT, _MULT = range(8)


@njit(**JIT)
def _trig(t, dim, x, s0, C):
    """cos/sin of every rod's angles into ``C`` (4, n)."""
    n = t.shape[1]
    for k in range(n):
        phi = x[s0 + k]
        C[0, k] = math.cos(phi)
        C[1, k] = math.sin(phi)
        if dim == 3:
            psi = x[s0 + n + k]
            C[2, k] = math.cos(psi)
            C[3, k] = math.sin(psi)


@njit(**JIT)
def _kappa(t, dim, x, xd, xdd, s0, C, K, with_qdd):
    """``kappa_k = r_k''`` (or ``J' q'`` when not ``with_qdd``) into ``K`` (3, n)."""
    n = t.shape[1]
    for k in range(n):
        s = t[_SIGN, k]
        if dim == 2:
            l, w, ld = x[s0 + n + k], xd[s0 + k], xd[s0 + n + k]
            wdd, ldd = (xdd[s0 + k], xdd[s0 + n + k]) if with_qdd else (0.0, 0.0)
            a0, a1 = el.rod_acceleration_2d(C[0, k], C[1, k], l, w, ld, wdd, ldd)
            K[0, k], K[1, k] = s * a0, s * a1
        else:
            l, w, v, ld = x[s0 + 2 * n + k], xd[s0 + k], xd[s0 + n + k], xd[s0 + 2 * n + k]
            if with_qdd:
                wdd, vdd, ldd = xdd[s0 + k], xdd[s0 + n + k], xdd[s0 + 2 * n + k]
            else:
                wdd, vdd, ldd = 0.0, 0.0, 0.0
            a0, a1, a2 = el.rod_acceleration_3d(C[0, k], C[1, k], C[2, k], C[3, k], l, w, v, ld, wdd, vdd, ldd)
            K[0, k], K[1, k], K[2, k] = s * a0, s * a1, s * a2


@njit(**JIT)
def _inverse_sample(t, g, dim, x, xd, xdd, o, s0, C, K, A, D):
    """Inverse dynamics of one sample at offset ``s0``: the forward pass (start-point
    accelerations), the backward pass (subtree sums), ``tau_k = J_k^T F_k``."""
    n = t.shape[1]
    _trig(t, dim, x, s0, C)
    _kappa(t, dim, x, xd, xdd, s0, C, K, True)
    for k in range(n):                         # forward pass, roots first: A_k = A_p + kappa_p, with g up
        p = int(t[_PARENT, k])
        for c in range(dim):
            A[c, k] = A[c, p] + K[c, p] if p >= 0 else (g if c == dim - 1 else 0.0)
            D[c, k] = 0.0
    for k in range(n - 1, -1, -1):             # backward pass, leaves first
        p = int(t[_PARENT, k])
        zeta, eta, theta = t[_ZETA, k], t[_ETA, k], t[_THETA, k]
        f0 = eta * A[0, k] + zeta * K[0, k] + D[0, k]
        f1 = eta * A[1, k] + zeta * K[1, k] + D[1, k]
        f2 = eta * A[2, k] + zeta * K[2, k] + D[2, k] if dim == 3 else 0.0
        if p >= 0:
            for c in range(dim):
                D[c, p] += theta * A[c, k] + eta * K[c, k] + D[c, k]
        s = t[_SIGN, k]
        if dim == 2:
            m0, m1 = el.project_2d(C[0, k], C[1, k], x[s0 + n + k], f0, f1)
            o[s0 + k], o[s0 + n + k] = s * m0, s * m1
        else:
            m0, m1, m2 = el.project_3d(C[0, k], C[1, k], C[2, k], C[3, k], x[s0 + 2 * n + k], f0, f1, f2)
            o[s0 + k], o[s0 + n + k], o[s0 + 2 * n + k] = s * m0, s * m1, s * m2


@njit(**JIT)
def _forward_sample(t, g, dim, x, xd, tau, o, s0, C, K, A, D):
    """Forward dynamics of one sample at offset ``s0``: ``b = J^-T tau - g_r``, ``r'' = mu^-1 b`` by
    the tree factor (``T^-T``, ``L^-1`` leaves first, ``D^-1 L^-T`` roots first, ``T^-1``),
    ``q'' = J^-1 (r'' - J' q')``."""
    n = t.shape[1]
    _trig(t, dim, x, s0, C)
    _kappa(t, dim, x, xd, xd, s0, C, K, False)
    for k in range(n):                         # A <- b = J^-T tau - g nu up
        s = t[_SIGN, k]
        if dim == 2:
            b0, b1 = el.unproject_2d(C[0, k], C[1, k], x[s0 + n + k], tau[s0 + k], tau[s0 + n + k])
            A[0, k], A[1, k] = s * b0, s * b1
        else:
            b0, b1, b2 = el.unproject_3d(C[0, k], C[1, k], C[2, k], C[3, k], x[s0 + 2 * n + k],
                                         tau[s0 + k], tau[s0 + n + k], tau[s0 + 2 * n + k])
            A[0, k], A[1, k], A[2, k] = s * b0, s * b1, s * b2
        A[dim - 1, k] -= g * t[_NU, k]
        for c in range(dim):
            D[c, k] = A[c, k]
    for k in range(n - 1, -1, -1):             # D <- T^-T b, then L^-1 (leaves first)
        p = int(t[_PARENT, k])
        if p >= 0:
            for c in range(dim):
                D[c, p] -= A[c, k]
    for k in range(n - 1, -1, -1):
        p = int(t[_PARENT, k])
        if p >= 0:
            lk = t[_MULT, k]
            for c in range(dim):
                D[c, p] -= lk * D[c, k]
    for k in range(n):                         # D^-1 L^-T, roots first (in place: the parent is done)
        p = int(t[_PARENT, k])
        d, lk = t[_PIVOT, k], t[_MULT, k]
        for c in range(dim):
            D[c, k] = D[c, k] / d - (lk * D[c, p] if p >= 0 else 0.0)
    for k in range(n - 1, -1, -1):             # T^-1, leaves first (the parent is still y_p)
        p = int(t[_PARENT, k])
        s = t[_SIGN, k]
        v0 = D[0, k] - (D[0, p] if p >= 0 else 0.0) - K[0, k]
        v1 = D[1, k] - (D[1, p] if p >= 0 else 0.0) - K[1, k]
        if dim == 2:
            a0, a1 = el.rates_2d(C[0, k], C[1, k], x[s0 + n + k], v0, v1)
            o[s0 + k], o[s0 + n + k] = s * a0, s * a1
        else:
            v2 = D[2, k] - (D[2, p] if p >= 0 else 0.0) - K[2, k]
            a0, a1, a2 = el.rates_3d(C[0, k], C[1, k], C[2, k], C[3, k], x[s0 + 2 * n + k], v0, v1, v2)
            o[s0 + k], o[s0 + n + k], o[s0 + 2 * n + k] = s * a0, s * a1, s * a2


@njit(**JIT)
def _block(t, g, dim, x, xd, y, o, start, stop, forward):
    """Samples ``start .. stop - 1`` into ``o`` (scratch allocated once)."""
    n = t.shape[1]
    C = np.zeros((4, n))
    K = np.zeros((3, n))
    A = np.zeros((3, n))
    D = np.zeros((3, n))
    for s in range(start, stop):
        if forward:
            _forward_sample(t, g, dim, x, xd, y, o, s * dim * n, C, K, A, D)
        else:
            _inverse_sample(t, g, dim, x, xd, y, o, s * dim * n, C, K, A, D)


@njit(**JIT)
def newton_euler(t, g, dim, forward, x, xd, y, o):
    """Every sample of the flat states, in turn, into ``o``: inverse dynamics (``y = qdd``, ``o = tau``)
    or, with ``forward``, forward dynamics (``y = tau``, ``o = qdd``)."""
    _block(t, g, dim, x, xd, y, o, 0, x.shape[0] // (dim * t.shape[1]), forward)


@njit(parallel=True, **JIT)
def newton_euler_parallel(t, g, dim, forward, x, xd, y, o):
    """:func:`newton_euler` with blocks of :data:`models.numba_threads.BLOCK` samples over numba's threads."""
    S = x.shape[0] // (dim * t.shape[1])
    for b in prange((S + BLOCK - 1) // BLOCK):
        _block(t, g, dim, x, xd, y, o, b * BLOCK, min(S, (b + 1) * BLOCK), forward)
