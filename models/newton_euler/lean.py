"""newton-euler's lean one-sample call: the per-sample inverse pass of
:mod:`exo_bench.models.newton_euler.compiled` as numba ``cfunc`` s (one per dimension) behind the C
wrapper of :mod:`exo_bench.models.runtime.lean_call`, the code of the ``lean`` kernel object of
:data:`exo_bench.models.newton_euler.kernels.NEWTON_EULER_KERNELS`.

``void f(double *p, double *q, double *qd, double *qdd, double *out, int64 n)``: ``p`` is the model's
``(8, n)`` table followed by ``g`` (:func:`params`) and the pass's ``(n, WIDTH)`` scratch (zeroed at
each call, as ``np.zeros`` did, in :func:`exo_bench.models.runtime.lean_call.block`: a call allocates
nothing), ``n`` the number of links; the wrapper has checked every array. The same function as the serial kernel's, :func:`~exo_bench.models.newton_euler.compiled._inverse_sample`,
on the same scratch row width, so the forces are bit-identical to it (tests/test_newton_euler_lean.py).
Imported on first use (compiling on a fresh machine, loading from numba's on-disk cache after)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import carray, cfunc, njit, types

from exo_bench.models.runtime.kernels import Entries
from exo_bench.models.newton_euler.compiled import WIDTH, _inverse_sample
from exo_bench.models.machine.numba_runtime import JIT

_P = types.CPointer(types.float64)
SIGNATURE = types.void(_P, _P, _P, _P, _P, types.int64)


@njit(inline="always", **JIT)  # in each cfunc's own code
def _sample(p, q, qd, qdd, o, n, dim):
    whole, d = carray(p, (8 * n + 1 + n * WIDTH,)), dim * n
    g, W = whole[8 * n], whole[8 * n + 1 :].reshape((n, WIDTH))
    W[:] = 0.0
    _inverse_sample(
        carray(p, (8, n)), g, dim, carray(q, (d,)), carray(qd, (d,)), carray(qdd, (d,)), carray(o, (d,)), 0, W
    )


@cfunc(SIGNATURE, cache=True)  # a cfunc is always compiled in nopython mode
def lean_c_2d(p, q, qd, qdd, o, n):
    _sample(p, q, qd, qdd, o, n, 2)


@cfunc(SIGNATURE, cache=True)
def lean_c_3d(p, q, qd, qdd, o, n):
    _sample(p, q, qd, qdd, o, n, 3)


CFUNCS = {2: lean_c_2d, 3: lean_c_3d}


def params(table: np.ndarray, g: float) -> np.ndarray:
    """The cfunc's ``p``: the C-ordered ``(8, n)`` table, then ``g``."""
    return np.concatenate([np.ascontiguousarray(table, dtype=np.float64).reshape(-1), [float(g)]])


def _declined(*args: Any, **kw: Any) -> None:
    """The wrapper's fallback: the call is not one it takes (the base class goes on)."""
    return None


def entries(model: Any) -> Entries:
    """The lean call bound to ``model`` (its ``table``, ``g`` and dimension), or no entry where the C
    wrapper was not built (the per-sample kernel's entry then runs)."""
    from exo_bench.models.runtime.lean_call import c_call

    address = getattr(CFUNCS[model.mechanism.dim], "address", None)  # None: NUMBA_DISABLE_JIT
    from exo_bench.models.states.states import validation_plan

    plan = validation_plan(model.mechanism)  # the C wrapper takes check=True too, validating first
    n = int(model.table.shape[1])
    call = c_call(address, params(model.table, model._g), _declined, model.dof, n, plan, scratch=n * WIDTH)
    return Entries() if call is None else Entries(lean=call)
