"""What every prepared model derives from its inverse dynamics: the mass matrix and the bias forces
(:func:`terms_from_inverse_dynamics`, one batched call), and forward dynamics by an equilibrated Cholesky
solve of ``M qdd = tau - h`` (:func:`cholesky_solve`, never NaN). Used by
:class:`~exo_bench.models.prepared.PreparedModel` where a method has no terms of its own."""

from __future__ import annotations

import numpy as np

from exo_bench.models.singularity import SingularConfigurationError


def terms_from_inverse_dynamics(inverse_dynamics, dof: int, q: np.ndarray, qd: np.ndarray):
    """``M (S, dof, dof)`` and ``h (S, dof)`` from any inverse dynamics ``(q, qd, qdd) -> tau`` on
    ``(samples, dof)`` arrays, in ONE batched call.

    Inverse dynamics is linear in ``qdd``: ``ID(q, qd, qdd) = M(q) qdd + h(q, qd)``. Per sample the
    batch holds ``(q, qd, 0)`` (gives ``h``), ``(q, 0, 0)`` (gravity only) and ``(q, 0, e_k)`` for
    every coordinate ``k``; then ``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)``. The subtraction costs at
    most ``eps * |gravity forces| / |M e_k|`` relative, which the tests bound against CRBA.
    """
    return terms_in_chunks(inverse_dynamics, dof, q, qd, (q.shape[0] + 1) * (dof + 2))


def terms_in_chunks(inverse_dynamics, dof: int, q: np.ndarray, qd: np.ndarray, chunk_samples: int):
    """:func:`terms_from_inverse_dynamics` over the rows of ``q, qd`` in chunks of fewer samples, so that
    their ``dof + 2`` inverse-dynamics rows per sample keep the working set of ``chunk_samples`` rows
    (one call where the batch fits)."""
    size, S, k = max(1, chunk_samples // (dof + 2)), q.shape[0], dof + 2
    M, h = np.empty((S, dof, dof)), np.empty((S, dof))
    for s0 in range(0, S, size):  # one batched call per chunk (no helper: one frame, issue 47)
        c = slice(s0, min(S, s0 + size))
        qc, n = q[c], min(S, s0 + size) - s0
        Q = np.repeat(qc, k, axis=0)  # (n*k, d): each sample's q, k times
        QD = np.zeros_like(Q)
        QD[::k] = qd[c]  # first row of each block: the real rates
        QDD = np.zeros_like(Q)
        rows = np.arange(n)[:, None] * k + 2 + np.arange(dof)[None, :]
        QDD[rows.ravel(), np.tile(np.arange(dof), n)] = 1.0
        tau = inverse_dynamics(Q, QD, QDD).reshape(n, k, dof)
        h[c] = tau[:, 0]
        M[c] = np.swapaxes(tau[:, 2:] - tau[:, 1:2], 1, 2)  # column k of M is ID(q, 0, e_k) - ID(q, 0, 0)
    return M, h


def cholesky_solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``M^-1 b`` for symmetric positive definite batches ``(S, d, d)``, ``(S, d)``: Cholesky of
    ``M`` equilibrated by ``D = diag(M)`` (units and coordinate scales drop out), then two
    triangular solves. A matrix that is not positive definite in floating point raises
    :class:`SingularConfigurationError` with its sample (never NaN)."""
    dg = np.diagonal(M, axis1=1, axis2=2)
    bad = ~(dg > 0).all(axis=1)
    if bad.any():
        s = int(np.argmax(bad))
        c = int(np.argmin(dg[s]))
        raise SingularConfigurationError(
            [
                f"sample {s}: M is numerically singular: its diagonal entry {c + 1} is "
                f"{float(dg[s, c])!r} (a rod within rounding of vertical or of length zero)"
            ]
        )
    r = 1.0 / np.sqrt(dg)
    try:
        L = np.linalg.cholesky(M * r[:, :, None] * r[:, None, :])
    except np.linalg.LinAlgError:
        raise SingularConfigurationError(
            [
                "M is not positive definite in floating point (numerically singular: "
                "a rod nearly vertical or nearly of length zero)"
            ]
        ) from None
    y = np.linalg.solve(L, (r * b)[..., None])
    return r * np.linalg.solve(np.swapaxes(L, 1, 2), y)[..., 0]
