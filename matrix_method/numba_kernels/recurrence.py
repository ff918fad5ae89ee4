"""Method ``recurrence``, compiled: the planar matrices grown link by link by eqs. (22)-(26), then the
corrected transitions (18) and the products of eq. (5)/(17).

Per sample, as :func:`exo_bench.matrix_method.recurrence.planar_step` does in numpy: the planar matrices start
at zero (the padding of eq. (24)) and adding link ``k`` adds ``delta X_n`` (eq. 25, generalised to
trees), the closed form of ``X`` evaluated with the increments of ``c`` of
:func:`exo_bench.matrix_method.closed_forms.coefficients.recurrence_increments`, on the rows and columns of k's ancestors
and k; the gravity vector and ``nu_s`` grow the same way. In 3D the recurrence runs for the
configuration and for the straightened model, then :func:`exo_bench.matrix_method.numba_kernels.matrix.spatial_matrices` and
:func:`exo_bench.matrix_method.numba_kernels.matrix.products` (eq. 26). The increments are per mechanism, packed once by
:func:`tables`.

Kernels: ``(params, ints, floats, q, qd, qdd)`` with ``params`` of :func:`exo_bench.matrix_method.numba_kernels.common.params`,
``ints, floats`` of :func:`tables` and flat ``(samples * dof,)`` states.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from exo_bench.matrix_method.closed_forms.coefficients import recurrence_increments
from exo_bench.models.machine.numba_runtime import JIT
from exo_bench.matrix_method.numba_kernels.common import (
    RATES_2D,
    RATES_3D,
    add_planar,
    add_planar_gravity,
    drivers,
)
from exo_bench.matrix_method.numba_kernels.matrix import products, spatial_matrices
from exo_bench.models.mechanism.mechanism import Mechanism


def tables(mech: Mechanism) -> tuple[np.ndarray, np.ndarray]:
    """The increments of eq. (25) for every link, packed for the kernels.

    ``ints``: ``ptr`` (``n + 1`` offsets), then the concatenated ``idx`` of every step (the ancestors of
    k, then k), ``idx`` of step k at ``ints[n + 1 + ptr[k] : n + 1 + ptr[k + 1]]``.
    ``floats``: per step, its ``dc`` (``m x m``, row-major) then its ``dnu_s`` (``m``), one step after
    the other (``m = ptr[k + 1] - ptr[k]``)."""
    n = mech.nlinks
    sizes = [len(mech.ancestors[k]) + 1 for k in range(n)]
    ptr = np.cumsum([0] + sizes)
    ints = np.empty(n + 1 + int(ptr[-1]), dtype=np.int64)
    ints[: n + 1] = ptr
    # written step by step into one array: the tables are alive once (n^3 / 3 floats for a chain,
    # 2.7 GB at n = 1000), never as blocks, their flattened copies and a concatenation at once
    floats = np.empty(sum(m * m + m for m in sizes))
    at = 0
    for k in range(n):
        idx, dc, dnu = recurrence_increments(mech, k)
        m = len(idx)
        ints[n + 1 + ptr[k] : n + 1 + ptr[k + 1]] = idx
        floats[at : at + m * m] = dc.ravel()
        floats[at + m * m : at + m * m + m] = dnu
        at += m * m + m
    ints.flags.writeable = floats.flags.writeable = False
    return ints, floats


@njit(**JIT)
def planar_recurrence(p, ints, floats, x, s0, dim, pl, ps, pP, nus, geo):
    """Eqs. (23)-(25) for trees: the planar matrices ``pl`` ``(8, n, n)`` and gravity ``pP`` ``(2, n)``
    of the sample at ``s0``, and (3D) ``ps`` of the straightened model, link by link; ``nus`` ``(n,)``
    accumulates the gravity coefficients; ``geo`` ``(2, n, n)`` and the last rows scratch."""
    n = p.shape[0]
    lo = s0 + (dim - 1) * n
    pl[:] = 0.0
    pP[:] = 0.0
    nus[:] = 0.0
    if dim == 3:
        ps[:] = 0.0
    for i in range(n):  # C_ij, S_ij once per sample
        for j in range(n):
            d = x[s0 + i] - x[s0 + j]
            geo[0, i, j] = math.cos(d)
            geo[1, i, j] = math.sin(d)
    off = 0
    for k in range(n):
        a0, m = n + 1 + ints[k], ints[k + 1] - ints[k]
        for a in range(m):
            i = ints[a0 + a]
            li = x[lo + i]
            for b in range(m):
                j = ints[a0 + b]
                lj = x[lo + j]
                dc = floats[off + a * m + b]
                C, S = geo[0, i, j], geo[1, i, j]
                add_planar(pl, i, j, dc, li, lj, C, S)  # delta X_n (25)
                if dim == 3:  # the straightened model
                    add_planar(ps, i, j, dc, li, lj, 1.0, 0.0)
            dnu = floats[off + m * m + a]
            phi = x[s0 + i]
            add_planar_gravity(pP, i, dnu, li, math.cos(phi), math.sin(phi))
            nus[i] += dnu
        off += m * m + m


@njit(**JIT)
def _sample(p, ints, floats, q, qd, qdd, o, s0, dim, pl, ps, pP, nus, geo, m3, P3, cs, xr):
    planar_recurrence(p, ints, floats, q, s0, dim, pl, ps, pP, nus, geo)
    if dim == 2:
        products(p, qd, qdd, o, s0, pl, pP, RATES_2D, xr)
    else:
        spatial_matrices(p, q, s0, pl, ps, nus, m3, P3, cs)  # eq. (26): 2D A_n+1 -> 3D A_n+1
        products(p, qd, qdd, o, s0, m3, P3, RATES_3D, xr)


@njit(**JIT)
def _scratch(n, dim):
    m3 = np.empty((24 if dim == 3 else 0, n, n))
    return (
        np.empty((8, n, n)),
        np.empty((8, n, n)),
        np.empty((2, n)),
        np.empty(n),
        np.empty((2, n, n)),
        m3,
        np.empty((3, n)),
        np.empty((2, n)),
        np.empty((8, n)),
    )


@njit(**JIT)
def _samples(p, ints, floats, q, qd, qdd, o, start, stop, dim):
    """Samples ``start .. stop - 1`` of the flat states into ``o`` (scratch allocated once)."""
    n = p.shape[0]
    pl, ps, pP, nus, geo, m3, P3, cs, xr = _scratch(n, dim)
    for s in range(start, stop):
        _sample(p, ints, floats, q, qd, qdd, o, s * dim * n, dim, pl, ps, pP, nus, geo, m3, P3, cs, xr)


#: dim -> (serial kernel, parallel kernel): recurrence_2d, recurrence_2d_parallel, recurrence_3d, recurrence_3d_parallel
KERNELS = drivers(
    __name__, "recurrence", "recurrence", {2: _samples, 3: _samples}, extra=("ints", "floats"), dim_argument=True
)
