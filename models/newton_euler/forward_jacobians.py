"""The Jacobians of forward dynamics from ``M^-1`` and the per-rod columns: O(n^2), one set of ``dof`` solves
(``M^-1 B`` column by column, compiled, below).

The implicit-function theorem on ``ID(q, qd, qdd) = tau`` gives ``dqdd/dq = -M^-1 dID/dq``, ``dqdd/dqd =
-M^-1 dID/dqd``, ``dqdd/dtau = M^-1``. With the structure of inverse dynamics
(:mod:`exo_bench.models.newton_euler.products`: ``dID/dq = blockdiag(P) + J^T (mu (x) I) A^q``, ``dID/dqd =
J^T (mu (x) I) A^r``) and ``M^-1 = J^-1 (mu^-1 (x) I) J^-T``, so that ``M^-1 J^T (mu (x) I) = J^-1``::

    dqdd/dq  = -M^-1 blockdiag(P) - blockdiag(J_i^-1 A^q_i),
    dqdd/dqd = -blockdiag(J_i^-1 A^r_i).

So the only dense part is ``M^-1`` (``dof`` columns of the O(n) forward dynamics,
:mod:`exo_bench.models.newton_euler.forward_jacobians`) and its product with a block-diagonal matrix (``dim``
multiply-adds per entry); the rest is O(n) per sample (the rates ``J_i^-1`` of each rod's columns,
:func:`exo_bench.models.newton_euler.passes.coordinate_rates`). ``dqdd/dqd`` is block diagonal: a rod's rates
change only its own centripetal and Coriolis terms ``J_i' q_i'``, and the rod-vector accelerations ``r''``
do not depend on the rates. Compared with applying ``M^-1`` to ``dID/dq`` and ``dID/dqd`` (``3 dof``
columns) this solves ``dof`` columns and needs no dense ``dID``.

**M^-1 B.** ``M(q)^-1 B`` column by column with the O(n) forward dynamics: no mass matrix, no dense LU.

``M = J^T (mu (x) I) J`` with ``J = blockdiag(s_i J_i(q_i))`` and the constant coupling ``mu`` factored
once (:mod:`exo_bench.models.mechanism.aggregates`), so ``M^-1 b = J^-1 mu^-1 J^-T b``: per column the loads
``J_i^-T b_i`` (:func:`exo_bench.models.mechanism.rod_elements.unproject_3d`), the tree solve with ``mu``
(three passes), and the rates ``J_i^-1`` (:func:`~exo_bench.models.mechanism.rod_elements.rates_3d`):
O(n) per column, O(n k) for ``k`` columns, O(n^2) for the ``(dof, dof)`` Jacobians of forward dynamics
(:mod:`exo_bench.models.derivatives`). It is forward dynamics at ``qd = 0`` and ``g = 0``, where the
bias ``J' q'`` and the weight vanish exactly.

* :func:`numpy_columns`: the numpy reference, :func:`exo_bench.models.newton_euler.passes.forward_dynamics`
  itself with the columns as samples (each column repeats its sample's ``q``).
* :func:`columns` / :func:`columns_parallel`: compiled, per sample the sines and cosines once and every
  column of ``B`` through the passes with the columns innermost (contiguous: numba vectorises them).
  ``out`` may be ``B`` itself: a sample's columns are read into scratch before any is written.

Singular at ``l_i = 0`` and (3D) ``cos psi_i = 0``, where ``J_i`` is; the callers refuse those states
first (:mod:`exo_bench.models.mechanism.singularity`).
"""

from __future__ import annotations

import math

import numpy as np
from exo_bench.models.machine.numba_runtime import JIT, SAMPLES_PER_TASK
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.compiled import _MULT, _PARENT, _PIVOT, _SIGN  # also registers the elements
from exo_bench.models.newton_euler.derivatives import rod_columns
from exo_bench.models.newton_euler.passes import Tree
from numba import njit, prange


def forward_jacobians(tree: Tree, dim: int, g: float, q, qd, qdd, Minv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(dqdd_dq, dqdd_dqd)``, ``(S, dof, dof)`` each, at ``(S, dof)`` states with ``qdd = FD(q, qd, tau)`` and
    ``Minv = M(q)^-1`` ``(S, dof, dof)`` (module docstring)."""
    n = tree.parent.shape[0]
    S, d = q.shape
    _, Aq, Ar, P = rod_columns(tree, dim, g, q, qd, qdd)  # (n, dim, dim, S): [link, row, column, sample]
    # -M^-1 blockdiag(P): column (b, j) is sum_a Minv[:, (a, j)] P_j[a, b], one (dof, dim) @ (dim, dim)
    # product per sample and rod (matmul: 10x numpy's einsum of the same contraction)
    MP = np.transpose(Minv.reshape(S, d, dim, n), (0, 3, 1, 2)) @ np.transpose(P, (3, 0, 1, 2))
    dq = np.negative(np.transpose(MP, (0, 2, 3, 1))).reshape(S, d, d)
    dqd = np.zeros((S, d, d))
    link = np.arange(n)
    for b in range(dim):  # column b of every rod at once: J_i^-1 A_i[:, b]
        Rq = passes.coordinate_rates(tree, dim, q, Aq[:, :, b, :])
        Rr = passes.coordinate_rates(tree, dim, q, Ar[:, :, b, :])
        for a in range(dim):
            rows, cols = a * n + link, b * n + link
            dq[:, rows, cols] -= Rq[:, rows]
            dqd[:, rows, cols] = -Rr[:, rows]
    return dq, dqd


def numpy_columns(tree: Tree, dim: int, q: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``M(q)^-1 B`` for ``q (S, dof)`` and ``B (S, dof, k)``, ``(S, dof, k)``: forward dynamics of the
    numpy reference at ``qd = 0``, ``g = 0``, one column per sample. Works on complex arrays."""
    S, d, k = B.shape
    qr = np.repeat(q, k, axis=0)
    cols = np.swapaxes(B, 1, 2).reshape(S * k, d)
    X = passes.forward_dynamics(tree, dim, 0.0, qr, np.zeros_like(qr), cols)
    return np.swapaxes(X.reshape(S, k, d), 1, 2)


@njit(**JIT)
def _sample(t, dim, x, B, O, C, L, Z):
    """One sample: ``O = M(x)^-1 B`` (``B``, ``O``: ``(dof, k)``), with the scratch ``C (n, 5)`` (cos phi,
    sin phi, cos psi, sin psi, l), ``L`` and ``Z`` ``(n, 3, k)`` (the loads and the tree solve)."""
    n, k = t.shape[1], B.shape[1]
    for i in range(n):  # the loads J^-T b and z = b, per link
        cf, sf = math.cos(x[i]), math.sin(x[i])
        cp, sp = (math.cos(x[n + i]), math.sin(x[n + i])) if dim == 3 else (1.0, 0.0)
        l, s = x[(dim - 1) * n + i], t[_SIGN, i]
        C[i, 0], C[i, 1], C[i, 2], C[i, 3], C[i, 4] = cf, sf, cp, sp, l
        for c in range(k):
            if dim == 2:
                b0, b1 = el.unproject_2d(cf, sf, l, B[i, c], B[n + i, c])
                b2 = 0.0
            else:
                b0, b1, b2 = el.unproject_3d(cf, sf, cp, sp, l, B[i, c], B[n + i, c], B[2 * n + i, c])
            L[i, 0, c], L[i, 1, c], L[i, 2, c] = s * b0, s * b1, s * b2
            Z[i, 0, c], Z[i, 1, c], Z[i, 2, c] = s * b0, s * b1, s * b2
    for i in range(n - 1, -1, -1):  # z <- L^-1 T^-T b, leaves first
        p = int(t[_PARENT, i])
        if p >= 0:
            m = t[_MULT, i]
            for e in range(dim):
                for c in range(k):
                    Z[p, e, c] -= L[i, e, c] + m * Z[i, e, c]
    for i in range(n):  # y <- D^-1 z - L^T y, roots first; r'' = y_i - y_p; q'' = s_i J_i^-1 r''
        p, d, m, s = int(t[_PARENT, i]), t[_PIVOT, i], t[_MULT, i], t[_SIGN, i]
        cf, sf, cp, sp, l = C[i, 0], C[i, 1], C[i, 2], C[i, 3], C[i, 4]
        for e in range(dim):
            for c in range(k):
                Z[i, e, c] = Z[i, e, c] / d - (m * Z[p, e, c] if p >= 0 else 0.0)
        for c in range(k):
            v0 = Z[i, 0, c] - (Z[p, 0, c] if p >= 0 else 0.0)
            v1 = Z[i, 1, c] - (Z[p, 1, c] if p >= 0 else 0.0)
            if dim == 2:
                a0, a1 = el.rates_2d(cf, sf, l, v0, v1)
                O[i, c], O[n + i, c] = s * a0, s * a1
            else:
                v2 = Z[i, 2, c] - (Z[p, 2, c] if p >= 0 else 0.0)
                a0, a1, a2 = el.rates_3d(cf, sf, cp, sp, l, v0, v1, v2)
                O[i, c], O[n + i, c], O[2 * n + i, c] = s * a0, s * a1, s * a2


@njit(**JIT)
def _block(t, dim, X, B, O, start, stop):
    n, k = t.shape[1], B.shape[2]
    C, L, Z = np.empty((n, 5)), np.empty((n, 3, k)), np.empty((n, 3, k))
    for s in range(start, stop):
        _sample(t, dim, X[s], B[s], O[s], C, L, Z)


@njit(**JIT)
def columns(t, dim, X, B, O):
    """``O[s] = M(X[s])^-1 B[s]`` for every sample in turn: ``X (S, dof)``, ``B`` and ``O`` ``(S, dof, k)``,
    C-ordered float64; ``t`` the tree's table (:meth:`exo_bench.models.newton_euler.passes.Tree.table`)."""
    _block(t, dim, X, B, O, 0, X.shape[0])


@njit(parallel=True, **JIT)
def columns_parallel(t, dim, X, B, O):
    """:func:`columns` over numba's threads, in blocks of :data:`exo_bench.models.machine.numba_runtime.SAMPLES_PER_TASK`."""
    S = X.shape[0]
    for b in prange((S + SAMPLES_PER_TASK - 1) // SAMPLES_PER_TASK):
        _block(t, dim, X, B, O, b * SAMPLES_PER_TASK, min(S, (b + 1) * SAMPLES_PER_TASK))
