"""The Jacobians of forward dynamics from ``M^-1``, compiled (numba): the formulas of
:mod:`exo_bench.models.newton_euler.forward_jacobians`, per sample, with the per-rod columns of
:mod:`exo_bench.models.newton_euler.derivative_elements` (no pass over the tree: the rod force is ``F_j =
J_j^-T tau_j``, exact at ``qdd = FD(q, qd, tau)`` where ``ID(q, qd, qdd) = tau``).

The signs cancel per rod: ``J_j^-1 (s_j A_j) = rates(A_j)`` and ``s_j d(J_j^T F_j)/dq_j`` with ``F_j = s_j
J_j^-T tau_j`` (unsigned elements) is ``d(J^T F)/dq`` of ``F = unproject(tau_j)``, all unsigned.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from exo_bench.models.newton_euler import derivatives_compiled  # noqa: F401 - registers the derivative elements
from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.newton_euler.compiled import newton_euler, newton_euler_parallel
from exo_bench.models.newton_euler.forward_jacobians import columns, columns_parallel
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.machine.numba_runtime import JIT, SAMPLES_PER_TASK


@njit(**JIT)
def _rod(dim, x, xd, xdd, tau, n, j, P, Aq, Ar):
    """Rod ``j``'s unsigned ``dim x dim`` blocks ``P = d(J^T F)/dq`` at ``F = J^-T tau_j``, ``J^-1 da/dq`` and
    ``J^-1 da/dqd`` (``[row, column]``)."""
    cf, sf = math.cos(x[j]), math.sin(x[j])
    if dim == 2:
        l, w, ld = x[n + j], xd[j], xd[n + j]
        f0, f1 = el.unproject_2d(cf, sf, l, tau[j], tau[n + j])
        p = de.projection_by_q_2d(cf, sf, l, f0, f1)
        aq = de.acceleration_by_q_2d(cf, sf, l, w, ld, xdd[j], xdd[n + j])
        ar = de.acceleration_by_rates_2d(cf, sf, l, w, ld)
        for b in range(2):
            P[0, b], P[1, b] = p[2 * b], p[2 * b + 1]
            Aq[0, b], Aq[1, b] = el.rates_2d(cf, sf, l, aq[2 * b], aq[2 * b + 1])
            Ar[0, b], Ar[1, b] = el.rates_2d(cf, sf, l, ar[2 * b], ar[2 * b + 1])
        return
    cp, sp = math.cos(x[n + j]), math.sin(x[n + j])
    l, w, v, ld = x[2 * n + j], xd[j], xd[n + j], xd[2 * n + j]
    f0, f1, f2 = el.unproject_3d(cf, sf, cp, sp, l, tau[j], tau[n + j], tau[2 * n + j])
    p3 = de.projection_by_q_3d(cf, sf, cp, sp, l, f0, f1, f2)
    aq3 = de.acceleration_by_q_3d(cf, sf, cp, sp, l, w, v, ld, xdd[j], xdd[n + j], xdd[2 * n + j])
    ar3 = de.acceleration_by_rates_3d(cf, sf, cp, sp, l, w, v, ld)
    for b in range(3):
        P[0, b], P[1, b], P[2, b] = p3[3 * b], p3[3 * b + 1], p3[3 * b + 2]
        Aq[0, b], Aq[1, b], Aq[2, b] = el.rates_3d(cf, sf, cp, sp, l, aq3[3 * b], aq3[3 * b + 1], aq3[3 * b + 2])
        Ar[0, b], Ar[1, b], Ar[2, b] = el.rates_3d(cf, sf, cp, sp, l, ar3[3 * b], ar3[3 * b + 1], ar3[3 * b + 2])


@njit(**JIT)
def _sample(dim, n, x, xd, xdd, tau, Minv, DQ, DQD, P, Aq, Ar):
    """One sample: ``DQ = -M^-1 blockdiag(P) - blockdiag(J^-1 A^q)``, ``DQD = -blockdiag(J^-1 A^r)``; the rods'
    blocks first (``P, Aq, Ar``: ``(n, 3, 3)`` scratch), then the product row by row with the rods innermost
    (contiguous in ``Minv`` and ``DQ``)."""
    d = dim * n
    for j in range(n):
        _rod(dim, x, xd, xdd, tau, n, j, P[j], Aq[j], Ar[j])
    for r in range(d):
        for c in range(d):
            DQD[r, c] = 0.0
        for b in range(dim):
            for j in range(n):
                acc = 0.0
                for a in range(dim):
                    acc += Minv[r, a * n + j] * P[j, a, b]
                DQ[r, b * n + j] = -acc
    for j in range(n):
        for a in range(dim):
            for b in range(dim):
                DQ[a * n + j, b * n + j] -= Aq[j, a, b]
                DQD[a * n + j, b * n + j] = -Ar[j, a, b]


@njit(**JIT)
def _block(dim, X, Xd, Xdd, T, Minv, DQ, DQD, start, stop):
    n = X.shape[1] // dim
    P, Aq, Ar = np.empty((n, 3, 3)), np.empty((n, 3, 3)), np.empty((n, 3, 3))
    for s in range(start, stop):
        _sample(dim, n, X[s], Xd[s], Xdd[s], T[s], Minv[s], DQ[s], DQD[s], P, Aq, Ar)


@njit(**JIT)
def forward_jacobians(dim, X, Xd, Xdd, T, Minv, DQ, DQD):
    """Every sample in turn: ``X, Xd, Xdd, T`` ``(S, dof)`` (``Xdd = FD(X, Xd, T)``), ``Minv`` ``(S, dof, dof)``,
    into ``DQ = dqdd/dq`` and ``DQD = dqdd/dqd`` ``(S, dof, dof)``; C-ordered float64."""
    _block(dim, X, Xd, Xdd, T, Minv, DQ, DQD, 0, X.shape[0])


@njit(parallel=True, **JIT)
def forward_jacobians_parallel(dim, X, Xd, Xdd, T, Minv, DQ, DQD):
    """:func:`forward_jacobians` over numba's threads, in blocks of :data:`exo_bench.models.machine.numba_runtime.SAMPLES_PER_TASK`."""
    S = X.shape[0]
    for b in prange((S + SAMPLES_PER_TASK - 1) // SAMPLES_PER_TASK):
        _block(dim, X, Xd, Xdd, T, Minv, DQ, DQD, b * SAMPLES_PER_TASK, min(S, (b + 1) * SAMPLES_PER_TASK))


@njit(**JIT)
def _eye(Minv):
    """``Minv[s] = I`` for every sample: the right-hand sides of ``M^-1 I``, solved in place."""
    for s in range(Minv.shape[0]):
        for i in range(Minv.shape[1]):
            for j in range(Minv.shape[2]):
                Minv[s, i, j] = 1.0 if i == j else 0.0


@njit(**JIT)
def forward_derivatives(t, g, dim, X, Xd, T, Xdd, Minv, DQ, DQD):
    """The kernels of ``model.derivatives.forward_dynamics`` in one compiled call, each sample in turn:
    ``Xdd = FD(X, Xd, T)`` (newton-euler's passes, :func:`exo_bench.models.newton_euler.compiled.newton_euler`),
    ``Minv = M^-1`` by ``dof`` columns of the O(n) forward dynamics
    (:func:`exo_bench.models.newton_euler.forward_jacobians.columns`), then :func:`forward_jacobians`: the same
    calls, in the same order, as one after another from Python."""
    newton_euler(t, g, dim, True, X.reshape(X.size), Xd.reshape(Xd.size), T.reshape(T.size), Xdd.reshape(Xdd.size))
    _eye(Minv)
    columns(t, dim, X, Minv, Minv)
    forward_jacobians(dim, X, Xd, Xdd, T, Minv, DQ, DQD)


@njit(**JIT)
def forward_derivatives_parallel(t, g, dim, X, Xd, T, Xdd, Minv, DQ, DQD):
    """:func:`forward_derivatives` with each kernel over numba's threads (their ``_parallel`` drivers)."""
    newton_euler_parallel(
        t, g, dim, True, X.reshape(X.size), Xd.reshape(Xd.size), T.reshape(T.size), Xdd.reshape(Xdd.size)
    )
    _eye(Minv)
    columns_parallel(t, dim, X, Minv, Minv)
    forward_jacobians_parallel(dim, X, Xd, Xdd, T, Minv, DQ, DQD)
