"""The kernels of the lean one-sample call as C functions (numba ``cfunc``), for the compiled wrapper
models/runtime/_lean_call.c (:mod:`exo_bench.models.runtime.lean_call`): ``void f(double *params, double *q, double *qd,
double *qdd, double *out, int64 n)``, the per-sample kernel of
:mod:`exo_bench.matrix_method.numba_kernels.factored` on raw pointers (the wrapper has checked every
array). ``params`` is :func:`exo_bench.models.runtime.lean_call.block`: the kernel's ``(n, n + 2)`` parameters,
then its ``(rows, n)`` scratch (:data:`SCRATCH_ROWS`), so a call allocates nothing; the same
per-sample function as the batch kernel's, so the forces are bit-identical. Imported on first use (compiling on a fresh machine, loading from numba's on-disk cache after)."""

from __future__ import annotations

from numba import carray, cfunc, types

from exo_bench.matrix_method.numba_kernels.factored import _sample_2d, _sample_3d

_P = types.CPointer(types.float64)
SIGNATURE = types.void(_P, _P, _P, _P, _P, types.int64)

#: dim -> rows of the per-sample kernel's scratch ``k`` (``(rows, n)``, after the parameters).
SCRATCH_ROWS = {2: 4, 3: 7}


@cfunc(SIGNATURE, cache=True)  # a cfunc is always compiled in nopython mode
def lean_c_2d(p, q, qd, qdd, o, n):
    a, d = n * (n + 2), 2 * n
    whole = carray(p, (a + 4 * n,))
    k = whole[a:].reshape((4, n))
    _sample_2d(
        whole[:a].reshape((n, n + 2)), carray(q, (d,)), carray(qd, (d,)), carray(qdd, (d,)), carray(o, (d,)), 0, k
    )


@cfunc(SIGNATURE, cache=True)  # a cfunc is always compiled in nopython mode
def lean_c_3d(p, q, qd, qdd, o, n):
    a, d = n * (n + 2), 3 * n
    whole = carray(p, (a + 7 * n,))
    k = whole[a:].reshape((7, n))
    _sample_3d(
        whole[:a].reshape((n, n + 2)), carray(q, (d,)), carray(qd, (d,)), carray(qdd, (d,)), carray(o, (d,)), 0, k
    )


CFUNCS = {2: lean_c_2d, 3: lean_c_3d}
