"""Directional derivatives of inverse dynamics through the Newton-Euler passes, O(n) per sample, numpy.

``tau = J^T F`` per rod (``J = blockdiag(s_i J_i(q_i))``) with the force ``F = (mu (x) I) kappa + g_r`` of
the two passes and each rod's acceleration ``kappa_i = s_i (J_i qdd_i + J_i' qd_i)``. With the per-rod
columns of :func:`exo_bench.models.newton_euler.derivatives_numpy.rod_columns` (``J_i``, ``A^q_i = d kappa_i
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
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.derivatives_numpy import rod_columns
from exo_bench.models.newton_euler.tree import Tree


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
