"""Method ``matrix-factored``'s forward dynamics of one sample, compiled: the code of the
``cholesky-forward`` kernel object (:data:`exo_bench.matrix_method.kernels.MATRIX_FACTORED_KERNELS`).

The batched route forms ``M`` and ``h`` from the factored inverse dynamics and solves ``M qdd = tau - h``
by Cholesky (``mass_matrix_and_bias``, :func:`exo_bench.models.runtime.prepared.cholesky_solve`): about
200 us for one exo5-3d sample in numpy calls. Here, in one compiled call and without forming ``M``:

* ``h = tau(q, qd, 0)``: the per-sample kernel of :mod:`~exo_bench.matrix_method.numba_kernels.factored`
  with ``qdd = 0``;
* ``M`` in factored form: every element of ``M`` is ``c_ij r_a,i . r_b,j`` (``kappa_j`` of a unit
  acceleration of coordinate b of link j is ``r_b,j``), so ``M = R^T (C x I) R`` with ``C`` the
  signed coupling ``c_ij`` and ``R`` block diagonal, one block ``R_i = [r_phi,i r_psi,i r_l,i]`` per
  link. The columns of ``R_i`` are orthogonal (``R_i^T R_i = D_i = diag(l^2 cos^2 psi, l^2, 1)``;
  2D ``diag(l^2, 1)``), so ``M^-1 b = D^-1 R^T C^-1 R D^-1 b``, per component of ``R D^-1 b`` two
  triangular solves with the Cholesky factor of ``C`` (computed once per model): O(n^2) a sample.
  ``R y`` is :func:`~exo_bench.matrix_method.closed_forms.factored.kappa_3d` with zero rates and
  accelerations ``y``, ``R^T u`` is :func:`~exo_bench.matrix_method.closed_forms.factored.forces_3d` of
  ``u`` with ``g = 0``: the element functions of every other kernel, no second derivation.

``M`` is singular exactly where a ``D_i`` is (a rod vertical or of length zero) or ``C`` is (the
mechanism is refused): :func:`forward_sample` answers False there, having written nothing into
``o`` (and where a length is not finite); its caller then takes the numpy route, which names why.
:func:`checked_forward` fuses it with the common-case checks of :mod:`exo_bench.models.runtime.forward_check`
(``_row_clear`` before, ``_finite`` after), answering :data:`DONE`, :data:`EXACT` (nothing computed:
the exact checks decide) or :data:`NOT_FINITE`. The result agrees with the batched route's to
rounding, not to the bit (tests/test_cholesky_forward.py).
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np
from numba import types

from exo_bench.matrix_method.closed_forms.factored import forces_2d, forces_3d, kappa_2d, kappa_3d
from exo_bench.matrix_method.numba_kernels.common import JIT, njit
from exo_bench.matrix_method.numba_kernels.factored import _sample_2d, _sample_3d
from exo_bench.models.runtime.forward_check import DONE, EXACT, NOT_FINITE, _finite, _row_clear
from exo_bench.models.machine.numba_runtime import jit_disabled
from exo_bench.models.states.validation_pass import LARGE, OK, STACK_DOUBLES, one_sample, stack_matrix


@njit(**JIT)
def _coupling_solve(lc, v):
    """``v = C^-1 v`` column by column (``v`` ``(d, n)``, the links on the fast axis) by the Cholesky
    factor ``lc`` of the coupling ``C = lc lc^T``: two triangular solves."""
    n = lc.shape[0]
    for a in range(v.shape[0]):
        for i in range(n):
            s = v[a, i]
            for j in range(i):
                s -= lc[i, j] * v[a, j]
            v[a, i] = s / lc[i, i]
        for i in range(n - 1, -1, -1):
            s = v[a, i]
            for j in range(i + 1, n):
                s -= lc[j, i] * v[a, j]
            v[a, i] = s / lc[i, i]


@njit(**JIT)
def _solve_2d(lc, x, k, b, o, v):
    """``o = M^-1 b`` of one planar sample, ``k`` holding ``cos phi, sin phi`` in rows 2, 3
    (:func:`_sample_2d`); False, ``o`` untouched, where a rod has a length that is zero or not finite."""
    n = lc.shape[0]
    for i in range(n):
        l = x[n + i]
        if not 0.0 < l * l < math.inf:
            return False
        v[0, i], v[1, i] = kappa_2d(l, 0.0, 0.0, b[i] / (l * l), b[n + i], k[2, i], k[3, i])  # R^-T b
    _coupling_solve(lc, v)
    for i in range(n):
        l = x[n + i]
        t_phi, t_l = forces_2d(l, k[2, i], k[3, i], v[0, i], v[1, i], 0.0)  # R^T u
        o[i], o[n + i] = t_phi / (l * l), t_l
    return True


@njit(**JIT)
def _solve_3d(lc, x, k, b, o, v):
    """``o = M^-1 b`` of one spatial sample, ``k`` holding the cosines and sines of phi, psi in rows
    3-6 (:func:`_sample_3d`); False, ``o`` untouched, where a rod is vertical or of length zero (or
    either is not finite)."""
    n = lc.shape[0]
    for i in range(n):
        l, cp = x[2 * n + i], k[5, i]
        if not (0.0 < l * l < math.inf and 0.0 < l * l * cp * cp < math.inf):
            return False
        w, vv = b[i] / (l * l * cp * cp), b[n + i] / (l * l)
        v[0, i], v[1, i], v[2, i] = kappa_3d(l, 0.0, 0.0, 0.0, w, vv, b[2 * n + i], k[3, i], k[4, i], cp, k[6, i])
    _coupling_solve(lc, v)
    for i in range(n):
        l, cp = x[2 * n + i], k[5, i]
        t = forces_3d(l, k[3, i], k[4, i], cp, k[6, i], v[0, i], v[1, i], v[2, i], 0.0)
        o[i], o[n + i], o[2 * n + i] = t[0] / (l * l * cp * cp), t[1] / (l * l), t[2]
    return True


@njit(**JIT)
def forward_sample(p, lc, x, xd, tau, o):
    """Forward dynamics of one sample (flat C-ordered ``(dof,)`` arrays, ``p`` of
    :func:`exo_bench.matrix_method.numba_kernels.common.params`, ``lc`` the Cholesky factor of its
    coupling) into ``o``; False, ``o`` untouched, where ``M`` is singular (a rod vertical or of
    length zero) or a length is not finite."""
    n, d = p.shape[0], x.shape[0]
    return _forward_into(p, lc, x, xd, tau, o, np.empty((7, n)), np.zeros((2, d)))


@njit(**JIT)
def _forward_into(p, lc, x, xd, tau, o, k, work):
    """:func:`forward_sample` with its scratch given: ``k`` ``(7, n)``, ``work`` ``(2, d)`` of zeros."""
    n, d = p.shape[0], x.shape[0]
    zero, b = work[0], work[1]
    if d == 2 * n:
        _sample_2d(p, x, xd, zero, b, 0, k)
    else:
        _sample_3d(p, x, xd, zero, b, 0, k)
    for i in range(d):
        b[i] = tau[i] - b[i]
    v = zero.reshape((d // n, n))  # h is in b: the zeros are scratch now
    if d == 2 * n:
        return _solve_2d(lc, x, k, b, o, v)
    return _solve_3d(lc, x, k, b, o, v)


@njit(**JIT)
def checked_forward(p, lc, plan, x, xd, tau, o):
    """One validated sample: :data:`EXACT` unless ``x`` clears the bounds of ``plan``
    (:func:`exo_bench.models.runtime.forward_check.plan`) and ``M`` is positive definite, else forward
    dynamics into ``o`` and :data:`DONE`, or :data:`NOT_FINITE` where an entry of ``o`` is not finite."""
    if not _row_clear(x, 0, x.shape[0], p.shape[0], plan):
        return EXACT
    if not forward_sample(p, lc, x, xd, tau, o):
        return EXACT
    return DONE if _finite(o) else NOT_FINITE


_LEAN: Any = {**JIT, "_nrt": False}  # Any: numba's stubs do not list _nrt


@njit(**_LEAN)
def forward_entry(p, lc, fplan, plan, x, xd, tau, o, check):
    """The compiled validate-and-compute entry of one sample (the ``cholesky-forward`` kernel's, called by
    the public call through :func:`entry`): the layout of the four arrays and, with ``check``, the checks
    of ``check=True`` (:func:`exo_bench.models.states.validation_pass.one_sample`), then :func:`checked_forward`'s
    work with its scratch on the stack: :data:`DONE` (0) with the accelerations in ``o``, or a code
    (a layout or value problem, a state near a bound of the regularity checks, ``M`` singular, an answer
    that is not finite), having written nothing into ``o``: its Python path then decides and names it. With ``check=False`` the regularity checks' common case runs too: where it does not clear, the
    Python path names a singular state as before."""
    code = one_sample(x, xd, tau, o, plan, check)
    if code != OK:
        return code
    n, d = p.shape[0], x.shape[0]
    if 7 * n + 3 * d > STACK_DOUBLES:
        return LARGE
    if not _row_clear(x, 0, d, n, fplan):
        return EXACT
    work = stack_matrix(2, d)
    for i in range(d):
        work[0, i] = 0.0
    res = stack_matrix(1, d)[0]  # the answer, copied into o only when done
    if not _forward_into(p, lc, x, xd, tau, res, stack_matrix(7, n), work):
        return EXACT
    if check and not _finite(res):
        return NOT_FINITE
    for i in range(d):  # o is written only when done
        o[i] = res[i]
    return DONE


@njit(**JIT)
def forward_batch(p, lc, fplan, x, xd, tau, o, check):
    """Forward dynamics of every sample of the C-ordered ``(samples, d)`` arrays into ``o``, one after
    another (:func:`forward_sample`'s arithmetic, its scratch made once); with ``check`` each sample first
    clears the bounds of ``fplan`` (:func:`exo_bench.models.runtime.forward_check.plan`) and its answer is finite.
    -1 when every sample is done, else the first sample that is not (``M`` singular, a bound, an answer
    that is not finite): the caller's checked path then decides and names it."""
    n, S, d = p.shape[0], x.shape[0], x.shape[1]
    k, work = np.empty((7, n)), np.empty((2, d))
    for s in range(S):
        if check and not _row_clear(x[s], 0, d, n, fplan):
            return s
        work[0, :] = 0.0
        if not _forward_into(p, lc, x[s], xd[s], tau[s], o[s], k, work):
            return s
        if check and not _finite(o[s]):
            return s
    return -1


def entry(p: np.ndarray, lc: np.ndarray) -> Any:
    """The compiled entry point of :func:`forward_entry` for the model's ``p`` and ``lc`` (or the function
    itself under ``NUMBA_DISABLE_JIT``)."""
    if jit_disabled():
        return forward_entry
    import numba

    one, vector = types.Array(types.float64, 1, "C"), types.Array(types.float64, 1, "A")
    plan = types.Array(types.int64, 1, "C")
    sig = (numba.typeof(p), numba.typeof(lc), one, plan, vector, vector, vector, vector, types.boolean)
    return forward_entry.compile(sig)


class Entries(NamedTuple):
    """The compiled entry points (or the functions run by Python under ``NUMBA_DISABLE_JIT``)."""

    forward_sample: Any
    checked_forward: Any
    forward_batch: Any


@functools.cache
def entries() -> Entries:
    """Resolved (compiled, or loaded from numba's on-disk cache) on the first call in a process."""
    if jit_disabled():
        return Entries(forward_sample, checked_forward, forward_batch)
    one, two = types.Array(types.float64, 1, "C"), types.Array(types.float64, 2, "C")
    p = types.Array(types.float64, 2, "C", readonly=True)  # the (n, n + 2) table of common.params
    return Entries(
        forward_sample.compile((p, two, one, one, one, one)),
        checked_forward.compile((p, two, one, one, one, one, one)),
        forward_batch.compile((p, two, one, two, two, two, two, types.boolean)),
    )
