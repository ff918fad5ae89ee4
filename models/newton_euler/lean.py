"""newton-euler's one sample with nothing but the arithmetic around it: the code of the ``lean`` kernel
object of :data:`exo_bench.models.newton_euler.kernels.NEWTON_EULER_KERNELS`.

:func:`inverse_entry` is the compiled validate-and-compute entry of inverse dynamics of one sample: the
layout of the four arrays and, with ``check``, the checks of ``check=True``
(:func:`exo_bench.models.validation_pass.one_sample`), then the per-sample inverse pass of
:mod:`exo_bench.models.newton_euler.compiled`, :func:`~exo_bench.models.newton_euler.compiled._inverse_sample`,
on a zeroed ``(n, WIDTH)`` scratch on the stack (as the serial kernel's ``np.zeros``): the forces are
bit-identical to the serial kernel's (tests/test_newton_euler_lean.py). It answers 0 (done) or the
problem's code, having written nothing; the public call then takes its Python path, which names it.
Compiled without numba's reference-counted runtime (unboxing an array allocates nothing).
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numba import njit, types

from exo_bench.models.newton_euler.compiled import WIDTH, _inverse_sample
from exo_bench.models.numba_runtime import JIT, jit_disabled
from exo_bench.models.validation_pass import LARGE, OK, STACK_DOUBLES, one_sample, stack_matrix

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
