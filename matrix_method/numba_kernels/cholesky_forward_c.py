"""``cholesky-forward``'s checked forward dynamics of one sample as a C function (numba ``cfunc``), for
the compiled wrapper models/runtime/_lean_call.c (:func:`exo_bench.models.runtime.lean_call.c_call` with ``forward``):
``int64 f(double *packed, double *q, double *qd, double *tau, double *out, int64 n)`` runs
:func:`~exo_bench.matrix_method.numba_kernels.cholesky_forward.checked_forward` on raw pointers (the
wrapper has checked every array and, with ``check=True``, validated the states) and answers its code
(:data:`~exo_bench.models.runtime.forward_check.DONE` is 0). ``packed`` is :func:`packed`: the kernel's
``(n, n + 2)`` parameters, the Cholesky factor of the coupling and the checks' plan in one array.
Imported on first use (compiling on a fresh machine, loading from numba's on-disk cache after)."""

from __future__ import annotations

import numpy as np
from numba import carray, cfunc, types

from exo_bench.matrix_method.numba_kernels.cholesky_forward import checked_forward
from exo_bench.models.runtime.forward_check import PLAN_SIZE

_P = types.CPointer(types.float64)
SIGNATURE = types.int64(_P, _P, _P, _P, _P, types.int64)


@cfunc(SIGNATURE, cache=True)  # a cfunc is always compiled in nopython mode
def checked_forward_c(packed, q, qd, tau, o, n):
    a, b = n * (n + 2), n * (2 * n + 2)
    whole = carray(packed, (b + PLAN_SIZE,))
    plan = whole[b:]
    d = int(plan[1]) * n  # plan[1]: the dimension (forward_check.plan)
    return checked_forward(
        whole[:a].reshape((n, n + 2)),
        whole[a:b].reshape((n, n)),
        plan,
        carray(q, (d,)),
        carray(qd, (d,)),
        carray(tau, (d,)),
        carray(o, (d,)),
    )


def packed(params: np.ndarray, lc: np.ndarray, plan: np.ndarray) -> np.ndarray:
    """The cfunc's first argument: ``params`` ``(n, n + 2)``, ``lc`` ``(n, n)`` and ``plan``, flat, C-ordered."""
    return np.concatenate([np.ravel(params), np.ravel(lc), np.ravel(plan)]).astype(np.float64)
