"""The Newton-Euler method, compiled (numba): the same passes as :mod:`exo_bench.models.newton_euler.passes`,
as loops over the links of one sample, and the lean one-sample entry of inverse dynamics around them.

Per sample the kernels call the very element functions of :mod:`exo_bench.models.mechanism.rod_elements`
(registered with numba once, by :func:`exo_bench.models.machine.numba_cache.inline`), so nothing physical is
written twice; tests/test_newton_euler.py holds them to the numpy reference. The layout follows the matrix family
(:mod:`exo_bench.matrix_method.numba_kernels.common`): flat C-ordered ``(samples * dof,)`` states and result, a serial
driver, and a parallel driver over blocks of :data:`exo_bench.models.machine.numba_runtime.SAMPLES_PER_TASK` samples for large
batches (:func:`exo_bench.models.machine.numba_runtime.run`). The per-mechanism numbers come as one ``(8, n)`` table
(:meth:`exo_bench.models.newton_euler.passes.Tree.table`) and ``g``.

Per sample: ``2n`` (2D) or ``4n`` (3D) sines and cosines and O(n) arithmetic, for inverse and
forward dynamics alike.

**The lean entry**: newton-euler's one sample with nothing but the arithmetic around it: the code of the ``lean`` kernel
object of :data:`exo_bench.models.newton_euler.kernels.NEWTON_EULER_KERNELS`.

:func:`inverse_entry` is the compiled validate-and-compute entry of inverse dynamics of one sample: the
layout of the four arrays and, with ``check``, the checks of ``check=True``
(:func:`exo_bench.models.states.validation_pass.one_sample`), then the per-sample inverse pass of
:mod:`exo_bench.models.newton_euler.compiled`, :func:`~exo_bench.models.newton_euler.compiled._inverse_sample`,
on a zeroed ``(n, WIDTH)`` scratch on the stack (as the serial kernel's ``np.zeros``): the forces are
bit-identical to the serial kernel's (tests/test_newton_euler_lean.py). It answers 0 (done) or the
problem's code, having written nothing; the public call then takes its Python path, which names it.
Compiled without numba's reference-counted runtime (unboxing an array allocates nothing).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numba
import numpy as np
from exo_bench.models.machine import numba_cache
from exo_bench.models.machine.numba_runtime import JIT, SAMPLES_PER_TASK, ensure, jit_disabled
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.states.validation_pass import LARGE, OK, STACK_DOUBLES, one_sample, stack_matrix
from numba import njit, prange, types

ensure()  # numba's runtime set-up (models/machine/numba_runtime.py), before the kernels below are defined

numba_cache.inline(el.ELEMENTS, Path(__file__).parent)  # registered once, keyed on rod_elements.py

_PARENT, _SIGN, _ZETA, _ETA, _THETA, _NU, _PIVOT, _MULT = range(8)
#: Columns of the per-link scratch row ``W[k]``: cos/sin of phi and psi, ``kappa`` (or ``J' q'``),
#: ``A`` (start-point acceleration with g; forward: the load ``b``), ``D`` (subtree sums; forward: the
#: tree solve's ``z``, then ``y``). One row per link keeps a link's numbers in one cache line.
_TRIG, _KAPPA, _A, _D = 0, 4, 7, 10
WIDTH = 16


@njit(**JIT)
def _rod(t, dim, x, xd, xdd, s0, k, w, with_qdd):
    """Link ``k``: cos/sin of its angles and ``kappa_k = r_k''`` (``J' q'`` without ``qdd``) into ``w``."""
    n = t.shape[1]
    s = t[_SIGN, k]
    cf = math.cos(x[s0 + k])
    sf = math.sin(x[s0 + k])
    w[0] = cf
    w[1] = sf
    if dim == 2:
        l = x[s0 + n + k]
        wdd, ldd = (xdd[s0 + k], xdd[s0 + n + k]) if with_qdd else (0.0, 0.0)
        a0, a1 = el.rod_acceleration_2d(cf, sf, l, xd[s0 + k], xd[s0 + n + k], wdd, ldd)
        a2 = 0.0
    else:
        cp = math.cos(x[s0 + n + k])
        sp = math.sin(x[s0 + n + k])
        w[2] = cp
        w[3] = sp
        l = x[s0 + 2 * n + k]
        if with_qdd:
            wdd, vdd, ldd = xdd[s0 + k], xdd[s0 + n + k], xdd[s0 + 2 * n + k]
        else:
            wdd, vdd, ldd = 0.0, 0.0, 0.0
        a0, a1, a2 = el.rod_acceleration_3d(
            cf, sf, cp, sp, l, xd[s0 + k], xd[s0 + n + k], xd[s0 + 2 * n + k], wdd, vdd, ldd
        )
    w[_KAPPA] = s * a0
    w[_KAPPA + 1] = s * a1
    w[_KAPPA + 2] = s * a2


@njit(inline="always", **JIT)  # in the passes' own code
def _store(t, dim, o, s0, k, a0, a1, a2):
    """Link ``k``'s coordinates ``a`` of its rod into ``o``, times the link's sign (3D: three of them)."""
    n = t.shape[1]
    s = t[_SIGN, k]
    o[s0 + k] = s * a0
    o[s0 + n + k] = s * a1
    if dim == 3:
        o[s0 + 2 * n + k] = s * a2


@njit(**JIT)
def _inverse_sample(t, g, dim, x, xd, xdd, o, s0, W):
    """Inverse dynamics of one sample at offset ``s0``: the forward pass (each rod's ``kappa`` and
    its start point's acceleration ``A_k = A_p + kappa_p``, with ``g up``), the backward pass (subtree
    sums ``D``), ``tau_k = J_k^T F_k``."""
    n = t.shape[1]
    for k in range(n):  # forward pass, roots first
        w = W[k]
        _rod(t, dim, x, xd, xdd, s0, k, w, True)
        p = int(t[_PARENT, k])
        if p >= 0:
            wp = W[p]
            w[_A] = wp[_A] + wp[_KAPPA]
            w[_A + 1] = wp[_A + 1] + wp[_KAPPA + 1]
            w[_A + 2] = wp[_A + 2] + wp[_KAPPA + 2]
        else:
            w[_A] = 0.0
            w[_A + 1] = g if dim == 2 else 0.0
            w[_A + 2] = g if dim == 3 else 0.0
        w[_D] = 0.0
        w[_D + 1] = 0.0
        w[_D + 2] = 0.0
    for k in range(n - 1, -1, -1):  # backward pass, leaves first
        w = W[k]
        zeta, eta, theta = t[_ZETA, k], t[_ETA, k], t[_THETA, k]
        f0 = el.rod_force(zeta, eta, w[_A], w[_KAPPA], w[_D])
        f1 = el.rod_force(zeta, eta, w[_A + 1], w[_KAPPA + 1], w[_D + 1])
        f2 = el.rod_force(zeta, eta, w[_A + 2], w[_KAPPA + 2], w[_D + 2])
        p = int(t[_PARENT, k])
        if p >= 0:
            wp = W[p]
            wp[_D] += el.subtree_share(theta, eta, w[_A], w[_KAPPA], w[_D])
            wp[_D + 1] += el.subtree_share(theta, eta, w[_A + 1], w[_KAPPA + 1], w[_D + 1])
            wp[_D + 2] += el.subtree_share(theta, eta, w[_A + 2], w[_KAPPA + 2], w[_D + 2])
        l, a2 = x[s0 + (dim - 1) * n + k], 0.0
        if dim == 2:  # tau_k = s_k J_k^T F_k
            a0, a1 = el.project_2d(w[0], w[1], l, f0, f1)
        else:
            a0, a1, a2 = el.project_3d(w[0], w[1], w[2], w[3], l, f0, f1, f2)
        _store(t, dim, o, s0, k, a0, a1, a2)


@njit(**JIT)
def _forward_sample(t, g, dim, x, xd, tau, o, s0, W):
    """Forward dynamics of one sample at offset ``s0``: ``b = J^-T tau - g_r`` and ``J' q'`` per rod;
    ``T^-T`` and ``L^-1`` in one pass leaves first (``z_p -= b_k + l_k z_k``); ``D^-1 L^-T`` roots
    first, where ``r_k'' = y_k - y_p`` (``T^-1``) is ready at once, and ``q_k'' = J_k^-1 (r_k'' - J_k' q_k')``."""
    n = t.shape[1]
    for k in range(n):
        w = W[k]
        _rod(t, dim, x, xd, xd, s0, k, w, False)  # kappa <- J' q'
        s = t[_SIGN, k]
        if dim == 2:
            b0, b1 = el.unproject_2d(w[0], w[1], x[s0 + n + k], tau[s0 + k], tau[s0 + n + k])
            b2 = 0.0
        else:
            b0, b1, b2 = el.unproject_3d(
                w[0], w[1], w[2], w[3], x[s0 + 2 * n + k], tau[s0 + k], tau[s0 + n + k], tau[s0 + 2 * n + k]
            )
        w[_A] = s * b0
        w[_A + 1] = s * b1
        w[_A + 2] = s * b2
        w[_A + dim - 1] -= g * t[_NU, k]  # - g_r: gravity along up
        w[_D] = w[_A]
        w[_D + 1] = w[_A + 1]
        w[_D + 2] = w[_A + 2]
    for k in range(n - 1, -1, -1):  # z <- L^-1 T^-T b, leaves first
        p = int(t[_PARENT, k])
        if p >= 0:
            w, wp, lk = W[k], W[p], t[_MULT, k]
            wp[_D] -= w[_A] + lk * w[_D]
            wp[_D + 1] -= w[_A + 1] + lk * w[_D + 1]
            wp[_D + 2] -= w[_A + 2] + lk * w[_D + 2]
    for k in range(n):  # y <- D^-1 z - L^T y, roots first; then r'' and q''
        w = W[k]
        p = int(t[_PARENT, k])
        d, lk = t[_PIVOT, k], t[_MULT, k]
        if p >= 0:
            wp = W[p]
            w[_D] = w[_D] / d - lk * wp[_D]
            w[_D + 1] = w[_D + 1] / d - lk * wp[_D + 1]
            w[_D + 2] = w[_D + 2] / d - lk * wp[_D + 2]
            v0 = w[_D] - wp[_D] - w[_KAPPA]
            v1 = w[_D + 1] - wp[_D + 1] - w[_KAPPA + 1]
            v2 = w[_D + 2] - wp[_D + 2] - w[_KAPPA + 2]
        else:
            w[_D] = w[_D] / d
            w[_D + 1] = w[_D + 1] / d
            w[_D + 2] = w[_D + 2] / d
            v0 = w[_D] - w[_KAPPA]
            v1 = w[_D + 1] - w[_KAPPA + 1]
            v2 = w[_D + 2] - w[_KAPPA + 2]
        l, a2 = x[s0 + (dim - 1) * n + k], 0.0
        if dim == 2:  # q_k'' = s_k J_k^-1 (r_k'' - J_k' q_k')
            a0, a1 = el.rates_2d(w[0], w[1], l, v0, v1)
        else:
            a0, a1, a2 = el.rates_3d(w[0], w[1], w[2], w[3], l, v0, v1, v2)
        _store(t, dim, o, s0, k, a0, a1, a2)


@njit(**JIT)
def _block(t, g, dim, x, xd, y, o, start, stop, forward):
    """Samples ``start .. stop - 1`` into ``o`` (scratch allocated once)."""
    n = t.shape[1]
    W = np.zeros((n, WIDTH))
    for s in range(start, stop):
        if forward:
            _forward_sample(t, g, dim, x, xd, y, o, s * dim * n, W)
        else:
            _inverse_sample(t, g, dim, x, xd, y, o, s * dim * n, W)


@njit(**JIT)
def newton_euler(t, g, dim, forward, x, xd, y, o):
    """Every sample of the flat states, in turn, into ``o``: inverse dynamics (``y = qdd``, ``o = tau``)
    or, with ``forward``, forward dynamics (``y = tau``, ``o = qdd``)."""
    _block(t, g, dim, x, xd, y, o, 0, x.shape[0] // (dim * t.shape[1]), forward)


@njit(parallel=True, **JIT)
def newton_euler_parallel(t, g, dim, forward, x, xd, y, o):
    """:func:`newton_euler` with blocks of :data:`exo_bench.models.machine.numba_runtime.SAMPLES_PER_TASK` samples over numba's threads."""
    S = x.shape[0] // (dim * t.shape[1])
    for b in prange((S + SAMPLES_PER_TASK - 1) // SAMPLES_PER_TASK):
        _block(t, g, dim, x, xd, y, o, b * SAMPLES_PER_TASK, min(S, (b + 1) * SAMPLES_PER_TASK), forward)


_LEAN: Any = {**JIT, "_nrt": False}  # Any: numba's stubs do not list _nrt


@njit(**_LEAN)
def inverse_entry(t, g, plan, q, qd, qdd, o, check):
    """One sample into ``o`` (module docstring): 0, or the code of what the caller names."""
    code = one_sample(q, qd, qdd, o, plan, check)
    if code != OK:
        return code
    n = t.shape[1]
    if n * WIDTH > STACK_DOUBLES:
        return LARGE
    W = stack_matrix(n, WIDTH)
    for k in range(n):
        for j in range(WIDTH):
            W[k, j] = 0.0
    _inverse_sample(t, g, q.shape[0] // n, q, qd, qdd, o, 0, W)
    return OK


_VECTOR = types.Array(types.float64, 1, "A")
_PLAN = types.Array(types.int64, 1, "C")


def entry(table: np.ndarray) -> Any:
    """The compiled entry point of :func:`inverse_entry` for the model's ``(8, n)`` table (None under
    ``NUMBA_DISABLE_JIT``: the public call's Python path runs)."""
    if jit_disabled():
        return None
    sig = (numba.typeof(table), types.float64, _PLAN, _VECTOR, _VECTOR, _VECTOR, _VECTOR, types.boolean)
    return inverse_entry.compile(sig)
