"""The analytic derivatives of inverse dynamics, numpy reference: vectorised over samples.

The algorithm (its derivation and why it is structured this way: :mod:`exo_bench.models.newton_euler.derivatives`):
per sample, the two passes give each rod's force ``F_i`` (:func:`exo_bench.models.newton_euler.passes.rod_forces`);
per rod the signed columns ``Y_j = s_j [d a_j/d q_j, d a_j/d qd_j, J_j]`` and the diagonal term ``s_i
d(J_i^T F)/d q_i`` (:mod:`exo_bench.models.newton_euler.derivative_elements`); then every block
``mu_ij J_i^T Y_j`` at once by ``einsum``.

Runs on complex arrays too (arithmetic, ``cos`` and ``sin`` only): tests/test_derivatives_analytic.py
differentiates it by complex steps. Arrays are batch-first: ``(S, dof)`` in, ``(S, dof, dof)`` out in
block order ``[phi..., psi..., l...]``.
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.tree import Tree


def _columns(parts, dim: int, sign: np.ndarray) -> np.ndarray:
    """Flat per-rod columns (column-major tuples of :mod:`.derivative_elements`, each ``(n, S)``) as
    ``(n, dim, dim, S)`` ``[link, component, column, sample]``, times the links' signs."""
    n, S = sign.shape[0], np.shape(parts[0])[-1]
    a = np.stack([np.broadcast_to(p, (n, S)) for p in parts]).reshape(dim, dim, n, S)
    return np.transpose(a, (2, 1, 0, 3)) * sign[:, None, None, None]


def rod_columns(tree: Tree, dim: int, g: float, q, qd, qdd):
    """Per rod, signed, ``(n, dim, dim, S)`` each: ``J_j``, ``d a_j/d q_j``, ``d a_j/d qd_j`` (``a_j = r_j''``),
    and ``s_i d(J_i^T F_i)/d q_i`` (``[link, row, column, sample]``), with ``F`` from the two passes."""
    n = tree.parent.shape[0]
    trig = passes._trig(dim, n, q)
    F = passes.rod_forces(tree, dim, g, passes.rod_accelerations(tree, dim, q, qd, qdd, trig))
    cf, sf, cp, sp = trig
    X, Xd, Xdd = q.T, qd.T, qdd.T
    l, s = X[(dim - 1) * n :], tree.sign
    if dim == 2:
        w, ld, wdd, ldd = Xd[:n], Xd[n:], Xdd[:n], Xdd[n:]
        J = de.jacobian_2d(cf, sf, l)
        Aq = de.acceleration_by_q_2d(cf, sf, l, w, ld, wdd, ldd)
        Ar = de.acceleration_by_rates_2d(cf, sf, l, w, ld)
        P = de.projection_by_q_2d(cf, sf, l, F[:, 0], F[:, 1])
    else:
        w, v, ld = Xd[:n], Xd[n : 2 * n], Xd[2 * n :]
        J = de.jacobian_3d(cf, sf, cp, sp, l)
        Aq = de.acceleration_by_q_3d(cf, sf, cp, sp, l, w, v, ld, Xdd[:n], Xdd[n : 2 * n], Xdd[2 * n :])
        Ar = de.acceleration_by_rates_3d(cf, sf, cp, sp, l, w, v, ld)
        P = de.projection_by_q_3d(cf, sf, cp, sp, l, F[:, 0], F[:, 1], F[:, 2])
    return tuple(_columns(x, dim, s) for x in (J, Aq, Ar, P))


def inverse_derivatives(tree: Tree, mu: np.ndarray, dim: int, g: float, q, qd, qdd):
    """``(dtau_dq, dtau_dqd, M)``, ``(S, dof, dof)`` each, of inverse dynamics at ``(S, dof)`` states
    (real or complex): ``dtau_i/dq_j = delta_ij s_i d(J_i^T F_i)/dq_i + mu_ij J_i^T s_j da_j/dq_j``,
    ``dtau_i/dqd_j = mu_ij J_i^T s_j da_j/dqd_j``, ``M_ij = mu_ij J_i^T J_j``."""
    n = tree.parent.shape[0]
    S, dof = q.shape
    J, Aq, Ar, P = rod_columns(tree, dim, g, q, qd, qdd)

    def blocks(Y):
        return np.einsum("ij,ieas,jebs->saibj", mu, J, Y).reshape(S, dof, dof)

    dq = blocks(Aq)
    link = np.arange(n)
    for a in range(dim):
        for b in range(dim):
            dq[:, a * n + link, b * n + link] += P[:, a, b].T
    return dq, blocks(Ar), blocks(J)
