"""sin and cos in branch-free arithmetic, for kernels that vectorise across samples.

numba calls libm's scalar ``sin``/``cos`` (SVML is not operational with the llvmlite here), and a
call in a loop stops LLVM from vectorising it. :func:`sincos_reduced` is the same mathematics as
libm's (fdlibm's, which glibc descends from) written without a branch, so that a loop over samples
that calls it compiles to SIMD instructions:

* **Reduction** (Cody-Waite, fdlibm's ``__ieee754_rem_pio2`` medium case): ``k = round(x 2/pi)``,
  ``y = x - k pi/2`` with ``pi/2`` split into three 33-bit parts and a tail (:data:`PIO2_1` ...),
  subtracted in turn: ``k * PIO2_1``, ``k * PIO2_2`` and ``k * PIO2_3`` are exact for
  ``|k| < 2^20``, and each subtraction is exact where it cancels (near a multiple of pi/2, where
  an error would be a large relative one) and rounded once where it does not. fdlibm also keeps the
  rounding error of the reduced argument as a tail, and its kernels correct the polynomials by
  it; that costs a third of the flops here and buys at most one ulp, so it is left out (the
  tail-corrected version measured 2.33 against 1.61 ns per angle, at most 1 ulp against 2);
* **Polynomials** (fdlibm's ``__kernel_sin``/``__kernel_cos`` minimax polynomials on
  ``[-pi/4, pi/4]``, error below 2^-58 relative, without the tail);
* **Quadrant** ``k mod 4`` in floating point (``floor``), the swap of sin and cos and the signs as
  selects: no branch, no integer conversion.

**Stated error bound**: for ``|x| <= RANGE`` (1e5 rad, about 16,000 turns), both results are within
:data:`ULPS` (2) ulp of numpy's (glibc's, correctly rounded in practice: at most 0.5 ulp from
exact). Measured on 2 million uniform arguments per range: at most 1 ulp for ``|x| <= 8`` (every
joint angle), 2 ulp in 1 of 2 million arguments up to 512, 6 up to 2048 and 0.14% of them up to 1e5.
tests/test_fast_trig.py asserts the bound over the range, at its edges, at the doubles nearest to
every multiple of pi/2 in it, where the reduction cancels, and at every quadrant boundary (the
largest reduced arguments), and 1 ulp over ``|x| <= 8``. ``sin(-0)`` gives +0 (the sign of a zero
is not kept). Outside the range (and for NaN and infinities) the kernels fall back to libm
(``math.sin``/``math.cos``) in a second, scalar loop that visits only those samples
(:func:`sincos_into`): a NaN angle gives NaN, never a number.

The reduction's products and Horner's steps are fused multiply-adds (:func:`fma`, LLVM's
``llvm.fma.f64``: one rounding each, 1.27 against 1.59 ns per angle with separate multiplies and
adds, 4096 angles in [-8, 8] in a loop, the quiet machine). Everything else is exact IEEE (no
``fastmath``: LLVM neither reassociates nor contracts it), so the result is the same on every SIMD
width and in scalar code. bench/perf/roofline.py counts its flops by running it on counting floats
(a fused multiply-add as two).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic, overload, register_jitable

#: ``|x|`` up to which the arithmetic path is used (and its error bound stated); beyond it, libm.
RANGE = 1e5
#: The stated bound of :func:`sincos_reduced` on ``|x| <= RANGE``: ulps from numpy's sin/cos.
ULPS = 2.0
#: ... and on ``|x| <= JOINT_RANGE`` (any joint angle, a few turns), where it is 1 ulp.
JOINT_RANGE, JOINT_ULPS = 8.0, 1.0

INVPIO2 = 6.36619772367581382433e-01  # 2/pi
PIO2_1 = 1.57079632673412561417e00  # first 33 bits of pi/2
PIO2_2 = 6.07710050630396597660e-11  # second 33 bits of pi/2
PIO2_3 = 2.02226624871116645580e-21  # third 33 bits of pi/2
PIO2_3T = 8.47842766036889956997e-32  # pi/2 - (PIO2_1 + PIO2_2 + PIO2_3)
ROUND = 6755399441055744.0  # 1.5 * 2^52: x + ROUND - ROUND rounds x to an integer

S1 = -1.66666666666666324348e-01  # fdlibm __kernel_sin
S2 = 8.33333333332248946124e-03
S3 = -1.98412698298579493134e-04
S4 = 2.75573137070700676789e-06
S5 = -2.50507602534068634195e-08
S6 = 1.58969099521155010221e-10
C1 = 4.16666666666666019037e-02  # fdlibm __kernel_cos
C2 = -1.38888888888741095749e-03
C3 = 2.48015872894767294178e-05
C4 = -2.75573143513906633035e-07
C5 = 2.08757232129817482790e-09
C6 = -1.13596475577881948265e-11


def fma(a, b, c):
    """``a * b + c`` rounded once (IEEE fusedMultiplyAdd): in compiled code LLVM's ``llvm.fma.f64``
    (one instruction here, the same bits in scalar and SIMD code), in Python exact rational
    arithmetic rounded to the nearest double."""
    a, b, c = float(a), float(b), float(c)
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(c)):
        return a * b + c
    return float(Fraction(a) * Fraction(b) + Fraction(c))


@intrinsic
def _llvm_fma(typingctx, a, b, c):
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        d = ir.DoubleType()
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(d, [d, d, d]), "llvm.fma.f64")
        return builder.call(fn, args)

    return sig, codegen


@overload(fma)
def _fma_compiled(a, b, c):
    def impl(a, b, c):
        return _llvm_fma(float(a), float(b), float(c))

    return impl


@register_jitable
def sincos_reduced(x):
    """``(sin x, cos x)`` for ``|x| <= RANGE``, branch-free (module docstring); outside the range
    the result is meaningless (use :func:`sincos` or :func:`sincos_into`)."""
    fn = fma(x, INVPIO2, ROUND) - ROUND  # k = round(x 2/pi), exact for |x| < 2^51
    r0 = fma(-fn, PIO2_1, x)  # exact: fn * PIO2_1 has at most 53 bits, and it cancels x
    r1 = fma(-fn, PIO2_2, r0)  # fn * PIO2_2 exact (|k| < 2^20); the difference exact where it cancels
    r2 = fma(-fn, PIO2_3, r1)  # likewise
    y0 = fma(-fn, PIO2_3T, r2)  # x - k pi/2, rounded once where it does not cancel
    z = y0 * y0
    # sin y0, fdlibm __kernel_sin(y0, 0, 0), Horner's steps fused
    v = z * y0
    ps = fma(z, fma(z, fma(z, fma(z, S6, S5), S4), S3), S2)
    s = fma(v, fma(z, ps, S1), y0)
    # cos y0, fdlibm __kernel_cos(y0, 0)
    z2 = z * z
    pc = fma(z, fma(z, fma(z, C3, C2), C1), z2 * z2 * fma(z, fma(z, C6, C5), C4))
    hz = 0.5 * z
    w1 = 1.0 - hz
    c = w1 + (((1.0 - w1) - hz) + z * pc)
    # quadrant k mod 4: sin x = (s, c, -s, -c)[k], cos x = (c, -s, -c, s)[k]
    quad = fn - 4.0 * math.floor(fn * 0.25)
    odd = (quad == 1.0) | (quad == 3.0)
    sa = c if odd else s
    ca = s if odd else c
    sx = -sa if quad >= 2.0 else sa
    cx = -ca if (quad == 1.0) | (quad == 2.0) else ca
    return sx, cx


@register_jitable
def in_range(x):
    """True where :func:`sincos_reduced` holds its bound (False for NaN and infinities too)."""
    return abs(x) <= RANGE


@register_jitable
def sincos(x):
    """``(sin x, cos x)``: :func:`sincos_reduced` in its range, libm outside it (one sample; in a
    loop over samples use :func:`sincos_into`, whose main loop has no branch)."""
    if abs(x) <= RANGE:
        return sincos_reduced(x)
    return math.sin(x), math.cos(x)


@register_jitable
def sincos_into(x, s, c, m):
    """``s[i], c[i] = sin x[i], cos x[i]`` for ``i < m``: one branch-free loop (SIMD) over every
    element, the ones outside ``RANGE`` computed at 0, then a scalar libm loop over those only."""
    outside = 0
    for i in range(m):
        xi = x[i]
        ok = abs(xi) <= RANGE
        si, ci = sincos_reduced(xi if ok else 0.0)
        s[i] = si
        c[i] = ci
        outside += 0 if ok else 1
    if outside:
        for i in range(m):
            xi = x[i]
            if not abs(xi) <= RANGE:
                s[i] = math.sin(xi)
                c[i] = math.cos(xi)


@njit(cache=True, nogil=True)
def sincos_array(x):
    """``(sin x, cos x)`` of a 1-D float64 array by :func:`sincos_into` (tests/test_fast_trig.py)."""
    s = np.empty_like(x)
    c = np.empty_like(x)
    sincos_into(x, s, c, x.shape[0])
    return s, c
