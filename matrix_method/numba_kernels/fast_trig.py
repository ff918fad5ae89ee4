"""The branch-free sin/cos of the kernels that vectorise across samples: :mod:`exo_bench.models.machine.fast_trig`.

It lives in the lowest layer (``models``) so that the Newton-Euler batched kernel
(:mod:`exo_bench.models.newton_euler.simd`) and the matrix family's (:mod:`exo_bench.matrix_method.numba_kernels.simd`)
share it; this module keeps the matrix family's name for it.
"""

from __future__ import annotations

from exo_bench.models.machine.fast_trig import (
    JOINT_RANGE,
    JOINT_ULPS,
    RANGE,
    ULPS,
    in_range,
    sincos,
    sincos_array,
    sincos_into,
    sincos_reduced,
)

__all__ = [
    "JOINT_RANGE",
    "JOINT_ULPS",
    "RANGE",
    "ULPS",
    "in_range",
    "sincos",
    "sincos_array",
    "sincos_into",
    "sincos_reduced",
]
