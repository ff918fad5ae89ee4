"""Where the limit is for the kernel that vectorises across samples (matrix_method/numba_kernels/simd.py).

Counted like :func:`exo_bench.bench.perf.roofline.count_factored`: the kernel's own steps (their ``py_func``) run one
sample on arrays of :class:`exo_bench.bench.perf.roofline.Counted` numbers, with the element functions and
the branch-free ``sin``/``cos`` (:func:`exo_bench.matrix_method.numba_kernels.fast_trig.sincos_reduced`, whose ``floor`` is
counted as one flop, and each fused multiply-add as two) as they are: every ``+``, ``-``, ``*`` and
``floor`` of the code that runs is counted, the arithmetic sine and cosine included; nothing is typed
by hand. Not counted: the
comparisons and selects of the range check and of the quadrant (one per result, a few per
angle), the loads and stores of the two transposes.

The limit of one sample is then its flops at the SIMD rate of :func:`exo_bench.bench.perf.roofline.throughput` (every
step of the kernel is a vectorised loop; no libm call is left for angles within the range).
"""

from __future__ import annotations

import math
import types

import numpy as np

from exo_bench.bench.perf.roofline import Counted, rebind
from exo_bench.models.mechanism.mechanism import Mechanism


def _floor(x):
    Counted.tally["add"] += 1
    return Counted(math.floor(float(x)))


def _fma(a, b, c):
    """A fused multiply-add (:func:`exo_bench.models.machine.fast_trig.fma`), counted as the multiply and the add it does."""
    from exo_bench.models.machine.fast_trig import fma

    Counted.tally["mul"] += 1
    Counted.tally["add"] += 1
    return Counted(fma(a, b, c))


def count_simd(mech: Mechanism, q, qd, qdd) -> tuple[dict[str, int], np.ndarray]:
    """Flops of one sample ``(dof,)`` of the SIMD kernel on ``mech`` (module docstring), and the
    forces that run computed (the compiled SIMD kernel's, to the bit: the same operations)."""
    from exo_bench.matrix_method.numba_kernels import common as compiled, simd as compiled_simd, fast_trig
    from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling, signed_gravity

    trig = fast_trig.sincos_reduced
    counted_trig = rebind(trig, math=types.SimpleNamespace(floor=_floor), fma=_fma)
    from exo_bench.models.machine import simd_angles

    compute = (compiled_simd._compute_2d if mech.dim == 2 else compiled_simd._compute_3d).py_func
    counted_compute = rebind(compute, link_pass=rebind(simd_angles.link_pass, sincos_reduced=counted_trig))
    n = mech.nlinks
    as_counted = np.vectorize(Counted, otypes=[object])
    p = as_counted(compiled.params(signed_coupling(mech), signed_gravity(mech), mech.g))
    x, xd, xdd = (as_counted(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    o = np.empty(mech.dof, dtype=object)
    W = np.empty(n * compiled_simd.ROWS * compiled_simd.LANES, dtype=object)
    F = np.empty(n * compiled_simd.FROWS * compiled_simd.LANES, dtype=object)
    Counted.tally = {"add": 0, "mul": 0, "trig": 0}
    compiled_simd._rows_in.py_func(x, xd, xdd, 0, 1, n, mech.dim, W)  # moves only
    counted_compute(p, 1, W, F)
    compiled_simd._rows_out.py_func(o, 0, 1, n, mech.dim, F)
    tally = dict(Counted.tally)
    tally["flops"] = tally["add"] + tally["mul"]
    tally["angles"] = (mech.dim - 1) * n
    return tally, o.astype(float)


def estimate_simd(count: dict[str, int], rates: dict[str, float], threads: int = 1) -> float:
    """Seconds per sample at the limit: the counted flops at the SIMD rate, on ``threads`` cores."""
    return count["flops"] / rates["simd_flops_per_s"] / threads
