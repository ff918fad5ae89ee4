"""The Jacobians of forward dynamics from ``M^-1`` and the per-rod columns: O(n^2), one set of ``dof`` solves.

The implicit-function theorem on ``ID(q, qd, qdd) = tau`` gives ``dqdd/dq = -M^-1 dID/dq``, ``dqdd/dqd =
-M^-1 dID/dqd``, ``dqdd/dtau = M^-1``. With the structure of inverse dynamics
(:mod:`exo_bench.models.newton_euler.products`: ``dID/dq = blockdiag(P) + J^T (mu (x) I) A^q``, ``dID/dqd =
J^T (mu (x) I) A^r``) and ``M^-1 = J^-1 (mu^-1 (x) I) J^-T``, so that ``M^-1 J^T (mu (x) I) = J^-1``::

    dqdd/dq  = -M^-1 blockdiag(P) - blockdiag(J_i^-1 A^q_i),
    dqdd/dqd = -blockdiag(J_i^-1 A^r_i).

So the only dense part is ``M^-1`` (``dof`` columns of the O(n) forward dynamics,
:mod:`exo_bench.models.newton_euler.inverse_mass`) and its product with a block-diagonal matrix (``dim``
multiply-adds per entry); the rest is O(n) per sample (the rates ``J_i^-1`` of each rod's columns,
:func:`exo_bench.models.newton_euler.passes.coordinate_rates`). ``dqdd/dqd`` is block diagonal: a rod's rates
change only its own centripetal and Coriolis terms ``J_i' q_i'``, and the rod-vector accelerations ``r''``
do not depend on the rates. Compared with applying ``M^-1`` to ``dID/dq`` and ``dID/dqd`` (``3 dof``
columns) this solves ``dof`` columns and needs no dense ``dID``.
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.derivatives import rod_columns
from exo_bench.models.newton_euler.passes import Tree


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
