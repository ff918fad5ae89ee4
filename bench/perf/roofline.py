"""Where the limit is: the arithmetic of one sample of the factored kernel, and this CPU's speed at it; the
same count for the kernels that vectorise across samples (the matrix family's and newton-euler's).

**Counting** (:func:`count_factored`). The compiled kernel's per-sample function
(:func:`exo_bench.matrix_method.numba_kernels.factored._sample_2d`/``_sample_3d``) is run as plain Python (its
``py_func``) on arrays of :class:`Counted` numbers, with ``math`` replaced by a namespace whose
``cos``/``sin`` count their calls: every ``+``, ``-`` and ``*`` of the real code is counted, nothing
is typed by hand, and an edit of the kernel changes the count. (The compiled code does the same
operations: numba compiles without ``fastmath``, so LLVM may not reassociate or drop any of them;
it may fuse a multiply and an add into one FMA instruction, which the estimate allows for.)

**Throughput** (:func:`throughput`), small numba loops compiled like the kernels (no fastmath):

* ``scalar_flops_per_s``: ``a_k = a_k * x + y`` on 16 independent scalar accumulators, two flops
  each (a multiply and an add: without ``fastmath`` numba does not fuse them), enough independent
  work to cover the latency: the scalar rate (numba runs LLVM's SLP vectorizer only when
  ``numba.config.SLP_VECTORIZE`` is on, off by default, which :func:`throughput` checks; so the
  accumulators stay scalar registers);
* ``simd_flops_per_s``: the same chain of 16 multiply-adds on every element of an array that stays
  in the L1 cache: LLVM vectorizes the loop over elements (AVX2/AVX-512 where the CPU has it);
* ``sincos_per_s``: ``sin`` and ``cos`` of every element of an array, the way the kernel calls
  them for each angle (libm's scalar functions, which LLVM may merge into one ``sincos``; numba
  does not vectorize them without Intel's SVML).

Each is the best of several repeats (the machine is shared). :func:`estimate` turns a count and
the rates into the seconds of one sample: its flops at the scalar or the SIMD rate, plus its
angles (``trig / 2`` sin-cos pairs) at the measured rate.
"""

from __future__ import annotations

import math
import time
import types

import numba
import numpy as np
from numba import njit

from exo_bench.models.mechanism.mechanism import Mechanism


class Counted(float):
    """A float whose arithmetic counts itself in :attr:`tally` (``add`` for ``+`` and ``-``, ``mul`` for ``*``)."""

    tally = {"add": 0, "mul": 0, "trig": 0}

    def _op(self, other, kind, fn):
        Counted.tally[kind] += 1
        return Counted(fn(float(self), float(other)))

    def __add__(self, o):
        return self._op(o, "add", lambda a, b: a + b)

    def __radd__(self, o):
        return self._op(o, "add", lambda a, b: b + a)

    def __sub__(self, o):
        return self._op(o, "add", lambda a, b: a - b)

    def __rsub__(self, o):
        return self._op(o, "add", lambda a, b: b - a)

    def __mul__(self, o):
        return self._op(o, "mul", lambda a, b: a * b)

    def __rmul__(self, o):
        return self._op(o, "mul", lambda a, b: b * a)

    def __neg__(self):
        return Counted(-float(self))  # a sign flip: no arithmetic


def _counting_math():
    def trig(fn):
        def f(x):
            Counted.tally["trig"] += 1
            return Counted(fn(float(x)))

        return f

    return types.SimpleNamespace(cos=trig(math.cos), sin=trig(math.sin))


def rebind(fn, **names):
    """``fn``'s Python function with some of its globals or closure variables replaced (the kernel's
    functions are closures of :func:`exo_bench.models.newton_euler.simd.build`)."""
    cells = (
        None
        if fn.__closure__ is None
        else tuple(
            types.CellType(names[v]) if v in names else c for v, c in zip(fn.__code__.co_freevars, fn.__closure__)
        )
    )
    return types.FunctionType(fn.__code__, {**fn.__globals__, **names}, fn.__name__, fn.__defaults__, cells)


def count_factored(mech: Mechanism, q, qd, qdd) -> tuple[dict[str, int], np.ndarray]:
    """Additions (and subtractions), multiplications and transcendental calls (cos, sin) of one
    sample ``(dof,)`` of method ``matrix-factored``'s compiled kernel on ``mech``, counted by running
    its per-sample function on :class:`Counted` numbers (module docstring); and the forces that run
    computed (equal to the compiled kernel's: the same operations in the same order)."""
    from exo_bench.matrix_method.numba_kernels import common as compiled, factored as compiled_factored
    from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling, signed_gravity

    fn = (compiled_factored._sample_2d if mech.dim == 2 else compiled_factored._sample_3d).py_func
    counted = types.FunctionType(fn.__code__, {**fn.__globals__, "math": _counting_math()}, fn.__name__)
    n = mech.nlinks
    as_counted = np.vectorize(Counted, otypes=[object])
    p = as_counted(compiled.params(signed_coupling(mech), signed_gravity(mech), mech.g))
    x, xd, xdd = (as_counted(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    o = np.empty(mech.dof, dtype=object)
    k = np.empty((4 if mech.dim == 2 else 7, n), dtype=object)
    Counted.tally = {"add": 0, "mul": 0, "trig": 0}
    counted(p, x, xd, xdd, o, 0, k)
    tally = dict(Counted.tally)
    tally["flops"] = tally["add"] + tally["mul"]
    return tally, o.astype(float)


@njit(cache=True)
def _scalar_fma(iters, x, y):
    a0, a1, a2, a3, a4, a5, a6, a7 = 1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7
    b0, b1, b2, b3, b4, b5, b6, b7 = 2.0, 2.1, 2.2, 2.3, 2.4, 2.5, 2.6, 2.7
    for _ in range(iters):
        a0 = a0 * x + y
        a1 = a1 * x + y
        a2 = a2 * x + y
        a3 = a3 * x + y
        a4 = a4 * x + y
        a5 = a5 * x + y
        a6 = a6 * x + y
        a7 = a7 * x + y
        b0 = b0 * x + y
        b1 = b1 * x + y
        b2 = b2 * x + y
        b3 = b3 * x + y
        b4 = b4 * x + y
        b5 = b5 * x + y
        b6 = b6 * x + y
        b7 = b7 * x + y
    return a0 + a1 + a2 + a3 + a4 + a5 + a6 + a7 + b0 + b1 + b2 + b3 + b4 + b5 + b6 + b7


@njit(cache=True)
def _simd_fma(a, reps, x, y):
    for _ in range(reps):
        for i in range(a.shape[0]):
            v = a[i]
            for _k in range(16):
                v = v * x + y
            a[i] = v
    return a[0]


@njit(cache=True)
def _sincos_loop(a, out, reps):
    for _ in range(reps):
        for i in range(a.shape[0]):
            x = a[i]
            c, s = math.cos(x), math.sin(x)  # as the kernel: cf, sf = math.cos(phi), math.sin(phi)
            out[i] = c * s
    return out[0]


def _best(fn, repeats: int = 5) -> float:
    best = math.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def scalar_rate(scale: int = 1) -> float:
    """Flops per second of :func:`_scalar_fma` as compiled in this process (see :func:`throughput`)."""
    x, y = 0.999999, 1e-7
    iters = 1_000_000 * scale
    _scalar_fma(10, x, y)
    return 2 * 16 * iters / _best(lambda: _scalar_fma(iters, x, y))


def throughput(scale: int = 1) -> dict[str, float]:
    """This CPU's scalar and SIMD multiply-add rate and ``sin`` rate, per second, from numba loops
    (module docstring); ``scale`` multiplies the loop lengths."""
    x, y = 0.999999, 1e-7  # |x| < 1: the values stay bounded
    if getattr(numba.config, "SLP_VECTORIZE", False):
        raise RuntimeError(
            "limit: numba's SLP vectorizer is on (NUMBA_SLP_VECTORIZE): the scalar rate would be a SIMD one"
        )
    scalar = scalar_rate(scale)
    a = np.random.default_rng(0).uniform(-np.pi, np.pi, 1024)
    reps = 2000 * scale
    b = np.random.default_rng(1).uniform(-1.0, 1.0, 1024)
    _simd_fma(b.copy(), 1, x, y)
    simd = 2 * 16 * b.size * reps / _best(lambda: _simd_fma(b, reps, x, y))
    out = np.empty_like(a)
    _sincos_loop(a, out, 1)
    sin_reps = 1000 * scale
    sincos = a.size * sin_reps / _best(lambda: _sincos_loop(a, out, sin_reps))
    return {"scalar_flops_per_s": scalar, "simd_flops_per_s": simd, "sincos_per_s": sincos}


def estimate(count: dict[str, int], rates: dict[str, float]) -> dict[str, float]:
    """Seconds of one sample at the measured rates: its flops at the scalar and at the SIMD rate,
    each plus its ``trig / 2`` sin-cos pairs (scalar calls either way)."""
    trig = count["trig"] / 2 / rates["sincos_per_s"]
    return {
        "scalar_s": count["flops"] / rates["scalar_flops_per_s"] + trig,
        "simd_s": count["flops"] / rates["simd_flops_per_s"] + trig,
        "trig_s": trig,
    }


# Where the limit is for the kernel that vectorises across samples (matrix_method/numba_kernels/simd.py).


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
    from exo_bench.matrix_method.numba_kernels import common as compiled, simd as compiled_simd
    from exo_bench.models.machine import fast_trig
    from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling, signed_gravity

    trig = fast_trig.sincos_reduced
    counted_trig = rebind(trig, math=types.SimpleNamespace(floor=_floor), fma=_fma)
    from exo_bench.models.machine import simd_blocks

    compute = (compiled_simd._compute_2d if mech.dim == 2 else compiled_simd._compute_3d).py_func
    counted_compute = rebind(compute, link_pass=rebind(simd_blocks.link_pass, sincos_reduced=counted_trig))
    n = mech.nlinks
    as_counted = np.vectorize(Counted, otypes=[object])
    p = as_counted(compiled.params(signed_coupling(mech), signed_gravity(mech), mech.g))
    x, xd, xdd = (as_counted(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    o = np.empty(mech.dof, dtype=object)
    W = np.empty(n * compiled_simd.ROWS * compiled_simd.LANES, dtype=object)
    F = np.empty(n * compiled_simd.FROWS * compiled_simd.LANES, dtype=object)
    Counted.tally = {"add": 0, "mul": 0, "trig": 0}
    simd_blocks._rows_in.py_func(x, xd, xdd, 0, 1, n, mech.dim, W)  # moves only
    counted_compute(p, 1, W, F)
    simd_blocks._rows_out.py_func(o, 0, 1, n, mech.dim, F)
    tally = dict(Counted.tally)
    tally["flops"] = tally["add"] + tally["mul"]
    tally["angles"] = (mech.dim - 1) * n
    return tally, o.astype(float)


def estimate_simd(count: dict[str, int], rates: dict[str, float], threads: int = 1) -> float:
    """Seconds per sample at the limit: the counted flops at the SIMD rate, on ``threads`` cores."""
    return count["flops"] / rates["simd_flops_per_s"] / threads


# Where the limit is for ``newton-euler``'s kernel that vectorises across samples (models/newton_euler/simd.py).


def _no_prefetch(*args) -> None:
    """The prefetches of the next block (no arithmetic, and no memory in this counting run)."""


def count_newton_euler_simd(mech: Mechanism, q, qd, qdd) -> tuple[dict[str, int], np.ndarray]:
    """Flops of one sample ``(dof,)`` of the newton-euler SIMD kernel on ``mech`` (module docstring),
    and the forces that run computed (the compiled SIMD kernel's, to the bit: the same operations)."""
    from exo_bench.models.machine import fast_trig, simd_blocks
    from exo_bench.models.newton_euler import simd
    from exo_bench.models.newton_euler.passes import prepare_tree
    from exo_bench.models.machine.simd_blocks import FROWS, LANES, ROWS, _rows_in_by_link, _rows_out_by_link

    trig = rebind(fast_trig.sincos_reduced, math=types.SimpleNamespace(floor=_floor), fma=_fma)
    start = rebind(simd._start_points.py_func)
    forward = rebind(
        (simd._forward_2d if mech.dim == 2 else simd._forward_3d).py_func,
        link_pass=rebind(simd_blocks.link_pass, sincos_reduced=trig),
        _start_points=start,
        prefetch_share=_no_prefetch,
    )
    backward = simd._backward.py_func
    n = mech.nlinks
    as_counted = np.vectorize(Counted, otypes=[object])
    t = as_counted(prepare_tree(mech).table())
    x, xd, xdd = (as_counted(np.asarray(a, dtype=float)) for a in (q, qd, qdd))
    o = np.empty(mech.dof, dtype=object)
    W = np.empty(n * ROWS * LANES, dtype=object)
    F = np.empty(n * FROWS * LANES, dtype=object)
    Counted.tally = {"add": 0, "mul": 0, "trig": 0}
    _rows_in_by_link.py_func(x, xd, xdd, 0, 1, n, mech.dim, W)  # moves only
    forward(t, Counted(float(mech.g)), 1, W, F, x, xd, xdd, o, 0, 0)
    backward(t, mech.dim, 1, W, F)
    _rows_out_by_link.py_func(o, 0, 1, n, mech.dim, F)
    tally = dict(Counted.tally)
    tally["flops"] = tally["add"] + tally["mul"]
    tally["angles"] = (mech.dim - 1) * n
    return tally, o.astype(float)


__all__ = ["count_newton_euler_simd", "estimate_simd"]
