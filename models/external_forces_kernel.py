"""The compiled pass of ``f_ext``: ``dest = tau - Q``, ``tau + Q`` or ``Q`` (:func:`apply`), with the
generalised forces ``Q(q, f_ext) = sum_k J_k^T f_k`` of :func:`exo_bench.models.external_forces.generalized_forces`.

Imported only by :func:`exo_bench.models.external_forces_compiled.kernel`, after numba's set-up. The
machine code is cached on disk (``cache=True``), keyed on this file, which therefore inlines nothing
from another: the rod projections of :mod:`exo_bench.models.rod_elements` (``project_2d``/``_3d``) are
written out here in the same expressions, so the numbers are the numpy ones to the last bit
(tests/test_external_forces.py and tests/test_external_forces_fast_path.py assert it; an edit there
that is not made here fails them).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def apply(params, q, f, tau, dest, mode, check):  # pragma: no cover - compiled
    """Status of ``dest = tau - Q`` (``mode < 0``), ``tau + Q`` (``> 0``) or ``Q`` (``0``, ``tau`` unread)
    over flat C-ordered float64 arrays (models/external_forces_compiled.py: the layout, the statuses):
    -2 and nothing written where the sizes disagree with ``params``; with ``check`` the flat index of
    the first force that is not finite, nothing written; else -1, done."""
    n = (params.shape[0] - 1) // 3
    dim = int(params[0])
    if n < 1 or dim < 2 or dim > 3 or params.shape[0] != 3 * n + 1:
        return -2
    dof = dim * n
    S = q.shape[0] // dof
    if q.shape[0] != S * dof or f.shape[0] != S * n * 3 * dim or dest.shape[0] != q.shape[0]:
        return -2
    if mode != 0 and tau.shape[0] != q.shape[0]:
        return -2
    for k in range(n):  # parents come before their children
        p = int(params[1 + k])
        if p != params[1 + k] or p < -1 or p >= k:
            return -2
    if check:
        for i in range(f.shape[0]):
            if not np.isfinite(f[i]):
                return i
    F = np.empty((n, dim))  # a link's own points weighted by their fractions, plus its subtree's whole
    through = np.empty((n, dim))  # what a link and its subtree pass to the parent
    Q = np.empty(dof)
    for s in range(S):
        o, g = s * dof, s * n * 3 * dim
        for k in range(n):
            nk = params[1 + 2 * n + k]
            for c in range(dim):
                a, b, e = f[g + 3 * k * dim + c], f[g + (3 * k + 1) * dim + c], f[g + (3 * k + 2) * dim + c]
                F[k, c] = 0.0 * a + nk * b + 1.0 * e
                through[k, c] = a + b + e
        for k in range(n - 1, -1, -1):  # leaves first
            p = int(params[1 + k])
            if p >= 0:
                for c in range(dim):
                    through[p, c] += through[k, c]
                    F[p, c] += through[k, c]
        for k in range(n):  # J^T F of each rod, signed (rod_elements.project_2d / project_3d)
            cf, sf, sk, fx, fy = np.cos(q[o + k]), np.sin(q[o + k]), params[1 + n + k], F[k, 0], F[k, 1]
            if dim == 2:
                l = q[o + n + k]  # noqa: E741 - the rod's length, as in rod_elements
                Q[k], Q[n + k] = sk * (l * (cf * fy - sf * fx)), sk * (cf * fx + sf * fy)
            else:
                cp, sp, l, fz = np.cos(q[o + n + k]), np.sin(q[o + n + k]), q[o + 2 * n + k], F[k, 2]  # noqa: E741
                radial = cf * fx + sf * fy
                Q[k] = sk * (l * cp * (cf * fy - sf * fx))
                Q[n + k] = sk * (l * (cp * fz - sp * radial))
                Q[2 * n + k] = sk * (cp * radial + sp * fz)
        for j in range(dof):
            if mode == 0:
                dest[o + j] = Q[j]
            elif mode > 0:
                dest[o + j] = tau[o + j] + Q[j]
            else:
                dest[o + j] = tau[o + j] - Q[j]
    return -1
