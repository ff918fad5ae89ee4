"""Method ``matrix-factored``, compiled: eq. (5)/(17) in factored form, no matrix formed.

The element functions of :mod:`exo_bench.matrix_method.closed_forms.factored` (which the numpy
kernel :func:`exo_bench.matrix_method.numpy_kernels.matrix._factored_2d` / ``_factored_3d`` calls on
arrays), called in loops over the links of one sample:

    kappa_j = (what link j's rates do to d2/dt2(l_j u_j)),  f_i = sum_j c_ij kappa_j,
    tau_a,i = r_a,i . f_i + g P_a,i,

per sample ``2n`` (2D) or ``4n`` (3D) sines and cosines, and ``2 n^2`` or ``3 n^2`` multiply-adds.
The kernels take ``(params, q, qd, qdd)`` with ``params`` of
:func:`exo_bench.matrix_method.numba_kernels.common.params` and flat ``(samples * dof,)`` states, and
return the flat forces. The physics of a link is :mod:`exo_bench.matrix_method.closed_forms.factored`
(shared with the SIMD kernel and the numpy one).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from exo_bench.matrix_method.closed_forms.factored import forces_2d, forces_3d, kappa_2d, kappa_3d
from exo_bench.matrix_method.numba_kernels.common import drivers
from exo_bench.models.machine.numba_runtime import JIT


@njit(**JIT)
def _sample_2d(p, x, xd, xdd, o, s0, k):
    """One planar sample at offset ``s0`` of the flat arrays; ``k`` ``(4, n)`` scratch."""
    n = p.shape[0]
    for j in range(n):
        phi, l = x[s0 + j], x[s0 + n + j]
        w, ld = xd[s0 + j], xd[s0 + n + j]
        wdd, ldd = xdd[s0 + j], xdd[s0 + n + j]
        cf, sf = math.cos(phi), math.sin(phi)
        k[0, j], k[1, j] = kappa_2d(l, w, ld, wdd, ldd, cf, sf)
        k[2, j] = cf
        k[3, j] = sf
    for i in range(n):
        f0 = 0.0
        f1 = 0.0
        for j in range(n):
            cij = p[i, j]
            f0 += cij * k[0, j]
            f1 += cij * k[1, j]
        cf, sf, l, gnu = k[2, i], k[3, i], x[s0 + n + i], p[i, n + 1] * p[i, n]
        o[s0 + i], o[s0 + n + i] = forces_2d(l, cf, sf, f0, f1, gnu)


@njit(**JIT)
def _sample_3d(p, x, xd, xdd, o, s0, k):
    """One spatial sample at offset ``s0`` of the flat arrays; ``k`` ``(7, n)`` scratch."""
    n = p.shape[0]
    for j in range(n):
        phi, psi, l = x[s0 + j], x[s0 + n + j], x[s0 + 2 * n + j]
        w, v, ld = xd[s0 + j], xd[s0 + n + j], xd[s0 + 2 * n + j]
        wdd, vdd, ldd = xdd[s0 + j], xdd[s0 + n + j], xdd[s0 + 2 * n + j]
        cf, sf = math.cos(phi), math.sin(phi)
        cp, sp = math.cos(psi), math.sin(psi)
        k[0, j], k[1, j], k[2, j] = kappa_3d(l, w, v, ld, wdd, vdd, ldd, cf, sf, cp, sp)
        k[3, j] = cf
        k[4, j] = sf
        k[5, j] = cp
        k[6, j] = sp
    for i in range(n):
        f0 = 0.0
        f1 = 0.0
        f2 = 0.0
        for j in range(n):
            cij = p[i, j]
            f0 += cij * k[0, j]
            f1 += cij * k[1, j]
            f2 += cij * k[2, j]
        cf, sf, cp, sp, l = k[3, i], k[4, i], k[5, i], k[6, i], x[s0 + 2 * n + i]
        o[s0 + i], o[s0 + n + i], o[s0 + 2 * n + i] = forces_3d(l, cf, sf, cp, sp, f0, f1, f2, p[i, n + 1] * p[i, n])


@njit(**JIT)
def _samples_2d(p, q, qd, qdd, o, start, stop):
    """Samples ``start .. stop - 1`` of the flat planar states into ``o`` (scratch allocated once)."""
    n = p.shape[0]
    k = np.empty((4, n))
    for s in range(start, stop):
        _sample_2d(p, q, qd, qdd, o, s * 2 * n, k)


@njit(**JIT)
def _samples_3d(p, q, qd, qdd, o, start, stop):
    """Samples ``start .. stop - 1`` of the flat spatial states into ``o`` (scratch allocated once)."""
    n = p.shape[0]
    k = np.empty((7, n))
    for s in range(start, stop):
        _sample_3d(p, q, qd, qdd, o, s * 3 * n, k)


#: dim -> (serial kernel, parallel kernel): factored_2d, factored_2d_parallel, factored_3d, factored_3d_parallel
KERNELS = drivers(__name__, "factored", "matrix-factored", {2: _samples_2d, 3: _samples_3d})
factored_2d, factored_3d = KERNELS[2][0], KERNELS[3][0]
