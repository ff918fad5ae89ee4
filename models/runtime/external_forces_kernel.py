"""The compiled pass of ``f_ext``: ``dest = tau - Q``, ``tau + Q`` or ``Q`` (:func:`apply`), with the
generalised forces ``Q(q, f_ext) = sum_k J_k^T f_k`` of :func:`exo_bench.models.runtime.external_forces.generalized_forces`.

Imported only by :func:`exo_bench.models.runtime.external_forces.kernel`, after numba's set-up. Each
rod's ``J^T F`` is the rod elements' own ``project_2d``/``project_3d`` (:mod:`exo_bench.models.mechanism.rod_elements`,
the functions the numpy reference and newton-euler's kernels call): nothing physical is written twice,
and the numbers are the numpy ones to the last bit (tests/test_external_forces.py and
tests/test_external_forces_fast_path.py assert it). The machine code is cached on disk (``cache=True``),
keyed on this file and on rod_elements.py (:data:`exo_bench.models.machine.numba_cache.KERNEL_SOURCES`): an edit to
an element recompiles this kernel (tests/test_external_forces_elements.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from exo_bench.models.machine import numba_cache
from exo_bench.models.mechanism.rod_elements import project_2d, project_3d

numba_cache.inline((project_2d, project_3d), __file__)  # callable from the kernel below, keyed on their file


@njit(cache=True, nogil=True)
def apply(params, q, f, tau, dest, mode, check):  # pragma: no cover - compiled
    """Status of ``dest = tau - Q`` (``mode < 0``), ``tau + Q`` (``> 0``) or ``Q`` (``0``, ``tau`` unread)
    over flat C-ordered float64 arrays (models/runtime/external_forces.py: the layout, the statuses):
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
        for k in range(n):  # J^T F of each rod (unsigned elements), signed
            cf, sf, sk = np.cos(q[o + k]), np.sin(q[o + k]), params[1 + n + k]
            if dim == 2:
                m_phi, f_l = project_2d(cf, sf, q[o + n + k], F[k, 0], F[k, 1])
                Q[k], Q[n + k] = sk * m_phi, sk * f_l
            else:
                cp, sp = np.cos(q[o + n + k]), np.sin(q[o + n + k])
                m_phi, m_psi, f_l = project_3d(cf, sf, cp, sp, q[o + 2 * n + k], F[k, 0], F[k, 1], F[k, 2])
                Q[k], Q[n + k], Q[2 * n + k] = sk * m_phi, sk * m_psi, sk * f_l
        for j in range(dof):
            if mode == 0:
                dest[o + j] = Q[j]
            elif mode > 0:
                dest[o + j] = tau[o + j] + Q[j]
            else:
                dest[o + j] = tau[o + j] - Q[j]
    return -1
