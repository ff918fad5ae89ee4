"""Method ``matrix-factored``, one sample per call with nothing but the arithmetic around it: the
code of the ``lean`` kernel object (:data:`exo_bench.matrix_method.kernels.MATRIX_FACTORED_KERNELS`).

:func:`inverse_2d` / :func:`inverse_3d` are the compiled validate-and-compute entries of inverse dynamics
of one sample: the layout of the four arrays (``dof`` entries, 8 bytes apart, aligned, ``out`` apart from
the inputs), with ``check`` the checks of ``check=True`` (finiteness, lengths >= 0, the force bound:
:func:`exo_bench.models.validation_pass.one_sample`), then the per-sample kernel of
:mod:`~exo_bench.matrix_method.numba_kernels.factored` into ``o`` with its scratch on the stack. They answer
0 (done) or the problem's code, having written nothing; the public call then takes its Python path, which
names the problem. The public call (models/prepared.py) calls them through the entry point that
:func:`entry` resolves once per model, after checking in Python what unboxing trusts: the arrays are
base-class ndarrays, 1-D, float64. Compiled without numba's reference-counted runtime: unboxing an array
then allocates nothing.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np
from numba import types

from exo_bench.matrix_method.numba_kernels.common import JIT, njit
from exo_bench.matrix_method.numba_kernels.factored import _sample_2d, _sample_3d
from exo_bench.models.validation_pass import LARGE, OK, STACK_DOUBLES, one_sample, stack_matrix

_LEAN: Any = {**JIT, "_nrt": False}  # Any: numba's stubs do not list _nrt


@njit(**_LEAN)
def inverse_2d(p, plan, q, qd, qdd, o, check):
    """One planar sample into ``o`` (module docstring): 0, or the code of what the caller names."""
    code = one_sample(q, qd, qdd, o, plan, check)
    if code != OK:
        return code
    n = p.shape[0]
    if 4 * n > STACK_DOUBLES:
        return LARGE
    _sample_2d(p, q, qd, qdd, o, 0, stack_matrix(4, n))
    return OK


@njit(**_LEAN)
def inverse_3d(p, plan, q, qd, qdd, o, check):
    """One spatial sample into ``o`` (module docstring): 0, or the code of what the caller names."""
    code = one_sample(q, qd, qdd, o, plan, check)
    if code != OK:
        return code
    n = p.shape[0]
    if 7 * n > STACK_DOUBLES:
        return LARGE
    _sample_3d(p, q, qd, qdd, o, 0, stack_matrix(7, n))
    return OK


KERNELS = {2: inverse_2d, 3: inverse_3d}

_VECTOR = types.Array(types.float64, 1, "A")
_PLAN = types.Array(types.int64, 1, "C")


def entry(dim: int, params: np.ndarray) -> Any:
    """The compiled entry point of :func:`inverse_2d`/:func:`inverse_3d` for ``params``, the validation
    plan and four 1-D float64 arrays of any stride (loaded from numba's on-disk cache, or compiled)."""
    sig = (numba.typeof(params), _PLAN, _VECTOR, _VECTOR, _VECTOR, _VECTOR, types.boolean)
    return KERNELS[dim].compile(sig)
