"""Method ``matrix-factored``, one sample per call with nothing but the arithmetic around it: the
code of the ``lean`` kernel object (:data:`exo_bench.matrix_method.kernels.MATRIX_FACTORED_KERNELS`).

A call of a numba kernel through its dispatcher types every argument and looks the signature up
(about 0.3 us on the 2-core machine, more than the arithmetic of exo5-3d). Two lean paths for one
sample on 1-D arrays, bound once per prepared model and held by the kernel's entries (nothing is
rebound on the model):

* **compiled** (:func:`c_call`, where setup.py built models/runtime/_lean_call.c): a small C callable
  that checks what memory safety needs (ndarray, one dimension of ``dof``, stride 8, float64, ``out``
  writable and apart from the inputs) and calls the kernel's numba ``cfunc``
  (matrix_method/numba_kernels/lean_c.py) with the raw pointers; every other form of the call goes to
  its fallback (which declines it: PreparedModel's call goes on, checks and names the field);
* **Python** (:func:`entry`, everywhere): the compiled entry point of :func:`lean_2d`/:func:`lean_3d`
  for one signature, resolved once and called directly: the arguments are unboxed as that
  signature says, without being typed. Unboxing trusts the dimension count and the dtype, so the
  caller checks those two in Python (``ndim == 1``, ``dtype is float64``, ``out`` writable: what
  unboxing cannot see); these functions check the rest in compiled code, in nanoseconds: every
  array has ``dof`` elements at a stride of 8 bytes (contiguous). They return False, having touched
  nothing, when a check fails; the caller then takes the checked path, which names the field.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types

from exo_bench.matrix_method.numba_kernels.common import JIT, njit
from exo_bench.matrix_method.numba_kernels.factored import factored_2d, factored_3d


@njit(**JIT)
def _fits(q, qd, qdd, o, dof):
    return (
        q.shape[0] == dof
        and qd.shape[0] == dof
        and qdd.shape[0] == dof
        and o.shape[0] == dof
        and q.strides[0] == 8
        and qd.strides[0] == 8
        and qdd.strides[0] == 8
        and o.strides[0] == 8
    )


@njit(**JIT)
def lean_2d(p, q, qd, qdd, o):
    """One planar sample into ``o`` if every array has ``2n`` contiguous elements; else False."""
    if not _fits(q, qd, qdd, o, 2 * p.shape[0]):
        return False
    factored_2d(p, q, qd, qdd, o)
    return True


@njit(**JIT)
def lean_3d(p, q, qd, qdd, o):
    """One spatial sample into ``o`` if every array has ``3n`` contiguous elements; else False."""
    if not _fits(q, qd, qdd, o, 3 * p.shape[0]):
        return False
    factored_3d(p, q, qd, qdd, o)
    return True


KERNELS = {2: lean_2d, 3: lean_3d}

_VECTOR = types.Array(types.float64, 1, "A")


def entry(dim: int, params: np.ndarray):
    """The compiled entry point of the lean kernel for ``params`` and four 1-D float64 arrays of any
    stride (loaded from numba's on-disk cache, or compiled, on first use)."""
    return KERNELS[dim].compile((numba.typeof(params), _VECTOR, _VECTOR, _VECTOR, _VECTOR))


def c_call(dim: int, params: np.ndarray, fallback, dof: int, plan: np.ndarray | None = None):
    """The compiled wrapper (models/runtime/_lean_call.c, :func:`exo_bench.models.runtime.lean_call.c_call`) around the
    kernel's cfunc (:mod:`exo_bench.matrix_method.numba_kernels.lean_c`): a callable with the arguments
    ``(q, qd, qdd, check, out)`` that runs one sample with ``check=False`` and ``out`` in C and passes
    every other call to ``fallback`` unchanged (``check=True`` too, given the mechanism's validation
    ``plan``); None where the extension was not built or ``params`` is not the ``(n, n + 2)`` table of
    the kernel."""
    from exo_bench.models.runtime.lean_call import c_call as wrap

    n = params.shape[0] if params.ndim == 2 else -1
    if params.shape != (n, n + 2):
        return None
    try:
        from exo_bench.models.runtime import _lean_call  # type: ignore[attr-defined]  # noqa: F401  # C, setup.py
    except ImportError:  # before the cfunc compiles
        return None
    from exo_bench.matrix_method.numba_kernels import lean_c as compiled_lean_c

    cfunc, rows = compiled_lean_c.CFUNCS[dim], compiled_lean_c.SCRATCH_ROWS[dim]
    return wrap(cfunc.address, params, fallback, dof, n, plan, scratch=rows * n)
