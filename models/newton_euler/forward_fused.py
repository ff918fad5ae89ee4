"""Forward dynamics of one sample checked in one compiled call: the ``tree-forward`` kernel's
(:mod:`exo_bench.models.newton_euler.kernels`). :func:`checked_forward` runs the common-case check of
:mod:`exo_bench.models.forward_check` (``clear``), newton-euler's forward passes
(:mod:`exo_bench.models.newton_euler.compiled`) and ``finite``, answering :data:`DONE`, :data:`EXACT`
(nothing computed: the exact checks decide) or :data:`NOT_FINITE`."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from exo_bench.models.numba_runtime import JIT, ensure, jit_disabled

ensure()  # numba's runtime set-up (models/numba_runtime.py), before the first kernel is defined

from numba import njit, types  # noqa: E402

from exo_bench.models.forward_check import _DIM, _G, DONE, EXACT, NOT_FINITE, _finite, _row_clear  # noqa: E402
from exo_bench.models.newton_euler.compiled import WIDTH, _forward_sample  # noqa: E402
from exo_bench.models.validation_pass import LARGE, OK, STACK_DOUBLES, one_sample, stack_matrix  # noqa: E402


@njit(**JIT)
def checked_forward(t, p, x, xd, tau, o):
    """One validated sample: :data:`EXACT` unless ``x`` clears the bounds, else forward dynamics into
    ``o`` and :data:`DONE`, or :data:`NOT_FINITE` where an entry of ``o`` is not finite."""
    n = t.shape[1]
    if not _row_clear(x, 0, x.shape[0], n, p):
        return EXACT
    _forward_sample(t, p[_G], int(p[_DIM]), x, xd, tau, o, 0, np.zeros((n, WIDTH)))
    return DONE if _finite(o) else NOT_FINITE


@njit(**JIT)
def checked_batch(t, p, x, xd, tau, o):
    """Every sample of the validated C-ordered ``(samples, dof)`` arrays, one after another, as
    :func:`checked_forward` (its scratch made once): -1 when every sample cleared the bounds and its
    answer is finite, else the first sample that did not (the caller's checked path decides and names it)."""
    n, S, d = t.shape[1], x.shape[0], x.shape[1]
    W = np.zeros((n, WIDTH))
    for s in range(S):
        if not _row_clear(x[s], 0, d, n, p):
            return s
        W[:] = 0.0
        _forward_sample(t, p[_G], int(p[_DIM]), x[s], xd[s], tau[s], o[s], 0, W)
        if not _finite(o[s]):
            return s
    return -1


@functools.cache
def batch_entry() -> Any:
    """The compiled entry point of :func:`checked_batch` (or the function itself under ``NUMBA_DISABLE_JIT``)."""
    if jit_disabled():
        return checked_batch
    one, two = types.Array(types.float64, 1, "C"), types.Array(types.float64, 2, "C")
    return checked_batch.compile((two, one, two, two, two, two))


_LEAN: Any = {**JIT, "_nrt": False}  # Any: numba's stubs do not list _nrt


@njit(**_LEAN)
def forward_entry(t, p, plan, x, xd, tau, o, check):
    """The compiled validate-and-compute entry of one sample (the ``tree-forward`` kernel's, called by the
    public call through :func:`lean_entry`): the layout of the four arrays and, with ``check``, the checks
    of ``check=True`` (:func:`exo_bench.models.validation_pass.one_sample`), then :func:`checked_forward`'s
    work on a zeroed scratch on the stack: :data:`DONE` (0) or a code, having written nothing into ``o``
    (its Python path then decides and names it). With ``check=False`` the regularity checks'
    common case runs too (a state it does not clear would divide by zero in the passes: the Python path
    names it)."""
    code = one_sample(x, xd, tau, o, plan, check)
    if code != OK:
        return code
    n = t.shape[1]
    if n * WIDTH + x.shape[0] > STACK_DOUBLES:
        return LARGE
    if not _row_clear(x, 0, x.shape[0], n, p):
        return EXACT
    d = x.shape[0]
    W = stack_matrix(n, WIDTH)
    for k in range(n):
        for j in range(WIDTH):
            W[k, j] = 0.0
    res = stack_matrix(1, d)[0]  # the answer, copied into o only when done
    _forward_sample(t, p[_G], int(p[_DIM]), x, xd, tau, res, 0, W)
    if check and not _finite(res):
        return NOT_FINITE
    for i in range(d):
        o[i] = res[i]
    return DONE


def lean_entry(table: np.ndarray) -> Any:
    """The compiled entry point of :func:`forward_entry` for the model's ``(8, n)`` table (None under
    ``NUMBA_DISABLE_JIT``: the public call's Python path runs)."""
    if jit_disabled():
        return None
    import numba

    one, vector = types.Array(types.float64, 1, "C"), types.Array(types.float64, 1, "A")
    plan = types.Array(types.int64, 1, "C")
    return forward_entry.compile((numba.typeof(table), one, plan, vector, vector, vector, vector, types.boolean))


@functools.cache
def entry() -> Any:
    """The compiled entry point of :func:`checked_forward` (or the function itself under
    ``NUMBA_DISABLE_JIT``), resolved on the first call in a process."""
    if jit_disabled():
        return checked_forward
    one, two = types.Array(types.float64, 1, "C"), types.Array(types.float64, 2, "C")
    return checked_forward.compile((two, one, one, one, one, one))
