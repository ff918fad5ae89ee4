"""Method ``matrix``, compiled: form every matrix of eq. (5)/(17), then the products with the rates.

Per sample, as :class:`exo_bench.matrix_method.prepared.MatrixProducts` does in numpy:

1. the planar matrices of eq. (5) (``A, Lambda, D, H`` of blocks ``phi`` and ``l``, and ``P``) from
   the closed forms of :mod:`exo_bench.matrix_method.closed_forms.planar` (:func:`planar_matrices`);
2. in 3D, the same for the straightened model (every ``phi = 0``), then every matrix of eq. (17)
   by the corrected transitions (18) of :mod:`exo_bench.matrix_method.closed_forms.transitions` (:func:`spatial_matrices`;
   nothing divides);
3. eq. (5)/(17): ``tau_k,i = sum_X sum_j X_ij x^X_j + g P_k,i`` with the rate vectors ``x^X`` of
   :data:`exo_bench.models.states.states.RATES` (:func:`products`).

The closed forms are the functions of ``planar.py`` and ``spatial.py`` themselves
(:mod:`exo_bench.matrix_method.numba_kernels.common` registers them with numba). Kernels: ``(params, q, qd, qdd)`` with
``params`` of :func:`exo_bench.matrix_method.numba_kernels.common.params` and flat ``(samples * dof,)`` states.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from exo_bench.matrix_method.closed_forms import transitions as spatial
from exo_bench.models.machine.numba_runtime import JIT
from exo_bench.matrix_method.numba_kernels.common import (
    drivers,
    PLANAR_FIELDS,
    RATES_2D,
    RATES_3D,
    Transition,
    set_planar,
    set_planar_gravity,
    set_spatial,
    set_spatial_gravity,
)

# The layouts the kernels index by number (checked here, so that a reordering of the closed-form
# tables cannot silently mismatch): planar matrix m of block b at index 4 b + m.
assert PLANAR_FIELDS == ("a_phi", "lam_phi", "d_phi", "h_phi", "a_l", "lam_l", "d_l", "h_l")
assert tuple(spatial.QUOTIENTS.values()) == (("phi", "A"), ("phi", "H"), ("l", "Lambda"), ("l", "D"))
assert tuple(spatial.PAIRS["phi"]) == ("A", "B", "Lambda", "D", "E", "G", "H", "K")


@njit(**JIT)
def planar_matrices(p, x, s0, dim, straight, pl, pP):
    """Eq. (5): the planar matrices ``pl`` ``(8, n, n)`` (``A, Lambda, D, H`` of block ``phi``, then of
    ``l``) and gravity vectors ``pP`` ``(2, n)`` at the angles ``phi`` and lengths ``l`` of the sample
    at ``s0`` (``straight``: every ``phi = 0``)."""
    n = p.shape[0]
    lo = s0 + (dim - 1) * n
    for i in range(n):
        li = x[lo + i]
        for j in range(n):
            lj = x[lo + j]
            c = p[i, j]
            if straight:
                C, S = 1.0, 0.0
            else:
                d = x[s0 + i] - x[s0 + j]
                C, S = math.cos(d), math.sin(d)
            set_planar(pl, i, j, c, li, lj, C, S)
        phi = 0.0 if straight else x[s0 + i]
        set_planar_gravity(pP, i, p[i, n], li, math.cos(phi), math.sin(phi))


@njit(**JIT)
def spatial_matrices(p, x, s0, pl, ps, nu_s, m3, P3, cs):
    """Eq. (18), corrected: every matrix of eq. (17), ``m3`` ``(24, n, n)`` (blocks ``phi, psi, l``, each
    ``A, B, Lambda, D, E, G, H, K``) and ``P3`` ``(3, n)``, from the planar matrices ``pl`` at the sample
    and ``ps`` of the straightened model, the gravity coefficients ``nu_s`` and the elevations
    ``psi`` of the sample at ``s0``; ``cs`` ``(2, n)`` scratch."""
    n = p.shape[0]
    for i in range(n):
        cs[0, i] = math.cos(x[s0 + n + i])
        cs[1, i] = math.sin(x[s0 + n + i])
    for i in range(n):
        li, ci, si = x[s0 + 2 * n + i], cs[0, i], cs[1, i]
        for j in range(n):
            t = Transition(
                pl[0, i, j],
                pl[1, i, j],
                pl[2, i, j],
                pl[3, i, j],
                pl[4, i, j],
                pl[5, i, j],
                pl[6, i, j],
                pl[7, i, j],
                ps[0, i, j],
                ps[3, i, j],
                ps[5, i, j],
                ps[6, i, j],
                li,
                x[s0 + 2 * n + j],
                ci,
                si,
                cs[0, j],
                cs[1, j],
            )
            set_spatial(m3, i, j, t)
        set_spatial_gravity(P3, i, nu_s[i], li, ci, si)
    for i in range(n):
        for j in range(n):
            m3[19, i, j] = spatial.d_l(m3[6, j, i])  # D_l = -(H_phi)^T


@njit(**JIT)
def products(p, xd, xdd, o, s0, mats, P, rates, xr):
    """Eq. (5)/(17): ``tau_k,i = sum_X sum_j X_ij x^X_j + g P_k,i`` into ``o`` at ``s0``, with ``mats``
    ``(blocks * names, n, n)``, ``P`` ``(blocks, n)`` and the rate table ``rates`` (one row per matrix
    name: factor, first block, second block or -1); ``xr`` ``(names, n)`` scratch."""
    n = p.shape[0]
    nm = rates.shape[0]
    nb = P.shape[0]
    g = p[0, n + 1]
    for k in range(nm):
        a, b = int(rates[k, 1]), int(rates[k, 2])
        for j in range(n):
            if b < 0:
                xr[k, j] = xdd[s0 + a * n + j]
            else:
                xr[k, j] = rates[k, 0] * xd[s0 + a * n + j] * xd[s0 + b * n + j]
    for blk in range(nb):
        for i in range(n):
            acc = g * P[blk, i]
            for k in range(nm):
                for j in range(n):
                    acc += mats[blk * nm + k, i, j] * xr[k, j]
            o[s0 + blk * n + i] = acc


@njit(**JIT)
def _sample_2d(p, q, qd, qdd, o, s0, pl, pP, xr):
    planar_matrices(p, q, s0, 2, False, pl, pP)
    products(p, qd, qdd, o, s0, pl, pP, RATES_2D, xr)


@njit(**JIT)
def _sample_3d(p, q, qd, qdd, o, s0, pl, ps, pP, m3, P3, cs, xr):
    planar_matrices(p, q, s0, 3, False, pl, pP)
    planar_matrices(p, q, s0, 3, True, ps, pP)
    spatial_matrices(p, q, s0, pl, ps, p[:, p.shape[0]], m3, P3, cs)
    products(p, qd, qdd, o, s0, m3, P3, RATES_3D, xr)


@njit(**JIT)
def _samples_2d(p, q, qd, qdd, o, start, stop):
    """Samples ``start .. stop - 1`` of the flat planar states into ``o`` (scratch allocated once)."""
    n = p.shape[0]
    pl, pP, xr = np.empty((8, n, n)), np.empty((2, n)), np.empty((4, n))
    for s in range(start, stop):
        _sample_2d(p, q, qd, qdd, o, s * 2 * n, pl, pP, xr)


@njit(**JIT)
def _samples_3d(p, q, qd, qdd, o, start, stop):
    """Samples ``start .. stop - 1`` of the flat spatial states into ``o`` (scratch allocated once)."""
    n = p.shape[0]
    pl, ps, pP = np.empty((8, n, n)), np.empty((8, n, n)), np.empty((2, n))
    m3, P3, cs, xr = np.empty((24, n, n)), np.empty((3, n)), np.empty((2, n)), np.empty((8, n))
    for s in range(start, stop):
        _sample_3d(p, q, qd, qdd, o, s * 3 * n, pl, ps, pP, m3, P3, cs, xr)


#: dim -> (serial kernel, parallel kernel): matrix_2d, matrix_2d_parallel, matrix_3d, matrix_3d_parallel
KERNELS = drivers(__name__, "matrix", "matrix", {2: _samples_2d, 3: _samples_3d})
