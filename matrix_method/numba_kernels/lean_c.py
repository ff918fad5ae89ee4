"""The kernels of the lean one-sample call as C functions (numba ``cfunc``), for the compiled wrapper
models/_lean_call.c (:mod:`exo_bench.models.lean_call`): ``void f(double *params, double *q, double *qd,
double *qdd, double *out, int64 n)``, the per-sample kernel of
:mod:`exo_bench.matrix_method.numba_kernels.factored` on raw pointers (the wrapper has checked every
array). Imported on first use (compiling on a fresh machine, loading from numba's on-disk cache after)."""

from __future__ import annotations

from numba import carray, cfunc, types

from exo_bench.matrix_method.numba_kernels.factored import factored_2d, factored_3d

_P = types.CPointer(types.float64)
SIGNATURE = types.void(_P, _P, _P, _P, _P, types.int64)


@cfunc(SIGNATURE, cache=True)  # a cfunc is always compiled in nopython mode
def lean_c_2d(p, q, qd, qdd, o, n):
    factored_2d(
        carray(p, (n, n + 2)), carray(q, (2 * n,)), carray(qd, (2 * n,)), carray(qdd, (2 * n,)), carray(o, (2 * n,))
    )


@cfunc(SIGNATURE, cache=True)  # a cfunc is always compiled in nopython mode
def lean_c_3d(p, q, qd, qdd, o, n):
    factored_3d(
        carray(p, (n, n + 2)), carray(q, (3 * n,)), carray(qd, (3 * n,)), carray(qdd, (3 * n,)), carray(o, (3 * n,))
    )


CFUNCS = {2: lean_c_2d, 3: lean_c_3d}
