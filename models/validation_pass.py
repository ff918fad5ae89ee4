"""The check of state arrays as one compiled pass: finiteness, rod lengths >= 0 and the force bound,
for one sample or a batch, answering with a small integer (issue 35).

:func:`status` reads ``q, qd, qdd`` (C-ordered float64, ``(dof,)`` or ``(samples, dof)``, one shape)
once each and answers :data:`OK`, :data:`NONFINITE` (a NaN or inf in any of them), :data:`NEGATIVE`
(a rod length below 0; ``-0.0`` is not), :data:`BOUND` (the forces could overflow float64:
:func:`exo_bench.models.validation.force_scale_log10` at the largest length, rate and acceleration
is not below ``limit``) or :data:`CONVERT` (not that layout: the caller converts at the edge and asks
again). Only when the answer is a problem does :func:`locate` find where it is, in the order the
messages name them (the first non-finite entry of ``q``, then of ``qd``, then of ``qdd``, row by row;
then the first negative length), and Python build the message (models/states.py).

How it is fast: the entries are read as the integers of their bits, whose magnitude ``bits & 0x7ff..f``
is at least ``0x7ff0..0`` exactly for NaN and inf, and orders finite magnitudes as the floats do: one
integer maximum per array (which LLVM vectorises; a float maximum it does not, without fast-math)
gives both the verdict on finiteness and the largest ``|qd|`` and ``|qdd|``. The lengths' sign bits
are OR-ed in the same pass over ``q`` (a mask per column, tiled over :data:`ROWS` rows so the inner
loop is long); only when a sign bit is set, or when the force bound at the largest ``|q|`` of any
coordinate is within :data:`MARGIN` of the limit, are the lengths read again exactly. The bound is
:func:`force_scale_from`'s arithmetic, the same logarithms in the same order (tests/test_validation_pass.py
checks both sides of the bound to the last ulp).

Compiled once per process: :func:`entries` resolves the compiled entry points for one signature each
(loaded from numba's on-disk cache after the first run: ``cache=True`` in :data:`JIT`, keyed on this
file, which inlines nothing from another), so a call types nothing. Unboxing trusts the dimension
count and the dtype: the caller checks those (``ndim``, ``dtype is float64``); the strides and shapes
are checked here. Under ``NUMBA_DISABLE_JIT`` the entries are the numpy reference
(:func:`reference_status`, :func:`reference_locate`), which the tests hold the compiled pass to.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from exo_bench.models.numba_runtime import JIT, ensure, jit_disabled
from exo_bench.models.validation import force_scale_from

ensure()  # numba's runtime set-up (models/numba_runtime.py), before the first kernel is defined

from llvmlite import ir  # noqa: E402 - numba's environment is checked before numba is imported
from numba import njit, types  # noqa: E402
from numba.extending import intrinsic  # noqa: E402
from numba.np.arrayobj import populate_array  # noqa: E402

#: The answers of :func:`status` and :func:`locate`.
OK, CONVERT, NONFINITE, NEGATIVE, BOUND = 0, 1, 2, 3, 4
#: Bits of ``present``: which of ``qd`` and ``qdd`` were given (the others are passed as ``q``).
QD, QDD = 1, 2
#: Rows of the column mask of the pass over ``q``: its inner loop runs over ``ROWS * dof`` entries, a
#: multiple of 16 (LLVM's vector width times its interleave), so none go to the scalar remainder.
ROWS = 32
#: The first entries of a plan (:func:`plan`): ``dof``, ``n`` and the bits of ``base``, ``lg_g``,
#: ``limit``; the column mask (``ROWS * dof`` entries) follows.
HEAD = 5
#: Below the limit by more than this, the bound at the largest ``|q|`` of any coordinate decides
#: without reading the lengths alone (the bound grows with the length; rounding is ~1e-13 here).
MARGIN = 1e-6

_ABS = 0x7FFF_FFFF_FFFF_FFFF
_INF = 0x7FF0_0000_0000_0000
_LOG4 = math.log10(4)


@intrinsic
def _int64_view(typingctx, arr):
    """The entries of a C-ordered array, flat, as an int64 array of their bits: a view of the same
    memory, built here (numba's ``carray`` is a jitted function, which without reference counting
    may return no new array)."""
    view = types.Array(types.int64, 1, "C")
    sig = view(arr)

    def codegen(context, builder, signature, args):
        src = context.make_array(signature.args[0])(context, builder, args[0])
        out = context.make_array(view)(context, builder)
        eight = context.get_constant(types.intp, 8)
        data = builder.bitcast(src.data, out.data.type)
        populate_array(out, data=data, shape=[src.nitems], strides=[eight], itemsize=eight, meminfo=None)
        return out._getvalue()

    return sig, codegen


@intrinsic
def _float_of(typingctx, bits):
    """The float64 whose bits are the int64 ``bits``."""
    sig = types.float64(types.int64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return sig, codegen


#: The options of :func:`status` and what it calls: :data:`JIT` without numba's reference-counted
#: memory (``_nrt``): unboxing an array then allocates nothing, which halves the cost of a call
#: (0.57 against 1.1 us for three arrays, measured on the loaded 2-core machine). Nothing in them allocates.
_LEAN: Any = {**JIT, "_nrt": False}  # Any: numba's stubs do not list _nrt


@njit(**_LEAN)
def _c_ordered(a, dof):
    """``a`` has ``dof`` columns, its entries lie in C order at 8 bytes apart (an empty array's
    strides do not matter) and its data is aligned to 8 bytes."""
    return (
        a.shape[-1] == dof
        and a.ctypes.data % 8 == 0
        and (a.size == 0 or (a.strides[-1] == 8 and (a.ndim == 1 or a.shape[0] == 1 or a.strides[0] == 8 * dof)))
    )


@intrinsic
def stack_matrix(typingctx, rows, cols):
    """A ``(rows, cols)`` C-ordered float64 array on the stack of the calling function (``alloca``,
    uninitialised): scratch that no other call or thread shares and that allocates nothing (numba's
    ``np.empty`` costs about 90 ns and needs its reference-counted runtime in the call). The callers
    bound its size by :data:`STACK_DOUBLES`."""
    view = types.Array(types.float64, 2, "C")
    sig = view(types.intp, types.intp)

    def codegen(context, builder, signature, args):
        r, c = args
        data = builder.alloca(ir.DoubleType(), size=builder.mul(r, c))
        out = context.make_array(view)(context, builder)
        eight = context.get_constant(types.intp, 8)
        populate_array(
            out, data=data, shape=[r, c], strides=[builder.mul(c, eight), eight], itemsize=eight, meminfo=None
        )
        return out._getvalue()

    return sig, codegen


#: The most doubles of :func:`stack_matrix` scratch a one-sample entry takes (64 KiB of stack); a larger
#: mechanism's one sample answers :data:`LARGE` and runs the serial kernel instead.
STACK_DOUBLES = 8192
#: The answer of a one-sample entry whose scratch would not fit :data:`STACK_DOUBLES`.
LARGE = 5


@njit(**_LEAN)
def _vector(a, dof):
    """A 1-D float64 array (typed so) of ``dof`` entries, 8 bytes apart, aligned: what a one-sample
    kernel indexes."""
    return a.shape[0] == dof and a.strides[0] == 8 and a.ctypes.data % 8 == 0


@njit(**_LEAN)
def _apart(o, a, dof):
    """The ``dof`` doubles of ``o`` and of ``a`` do not overlap."""
    lo, hi = o.ctypes.data, a.ctypes.data
    return lo + 8 * dof <= hi or hi + 8 * dof <= lo


@njit(**_LEAN)
def one_sample(q, qd, y, o, plan, check):
    """The gate and the checks of one sample in compiled code, for the one-sample entries of the
    kernels: :data:`CONVERT` unless ``q, qd, y`` and ``o`` (1-D float64 arrays: the caller checked the
    type, the dimension count and the dtype, which unboxing trusts) each have ``plan[0]`` entries 8
    bytes apart, aligned, and ``o`` overlaps none of the others; then, with ``check``, :func:`status`
    of the three. :data:`OK` or the problem's code: the caller's Python path then names it."""
    dof = plan[0]
    if not (_vector(q, dof) and _vector(qd, dof) and _vector(y, dof) and _vector(o, dof)):
        return CONVERT
    if not (_apart(o, q, dof) and _apart(o, qd, dof) and _apart(o, y, dof)):
        return CONVERT
    if check:
        return status(q, qd, y, QD | QDD, plan)
    return OK


@njit(**_LEAN)
def _magnitude(b):
    """The largest ``bits & _ABS``: at least ``_INF`` iff some entry is NaN or inf; else the bits of
    the largest ``|x|``."""
    m = 0
    for i in range(b.size):
        m = max(m, b[i] & _ABS)
    return m


@njit(**_LEAN)
def _scan_q(b, dof, n, mask):
    """:func:`_magnitude` of ``q`` and the OR of the bits of its last ``n`` columns (negative if some
    length has its sign bit set: negative, or ``-0.0``), in one pass; ``mask`` is -1 on the length
    columns of :data:`ROWS` rows, 0 elsewhere."""
    width = mask.size
    top, signs = 0, 0
    for k in range(b.size // width):
        block = b[k * width : (k + 1) * width]
        for j in range(width):
            v = block[j]
            top = max(top, v & _ABS)
            signs |= v & mask[j]
    for s in range(b.size // width * ROWS, b.size // dof):
        row = b[s * dof : (s + 1) * dof]
        for c in range(dof):
            top = max(top, row[c] & _ABS)
        for c in range(dof - n, dof):
            signs |= row[c]
    return top, signs


@njit(**_LEAN)
def _lengths(b, dof, n):
    """The bits of the largest ``|l|`` and of the largest negative length's magnitude (0: none)."""
    top, negative = 0, 0
    for s in range(b.size // dof):
        for c in range(s * dof + dof - n, (s + 1) * dof):
            v = b[c]
            top = max(top, v & _ABS)
            if v < 0 and v & _ABS > 0:
                negative = max(negative, v & _ABS)
    return top, negative


@njit(**_LEAN)
def _lg(x):
    return math.log10(x) if x > 0 else -math.inf


@njit(**_LEAN)
def _scale(length, rate, acceleration, base, lg_g):
    """:func:`exo_bench.models.validation.force_scale_from`, the same operations in the same order."""
    return base + 2 * _lg(1.0 + length) + (max(0.0, _lg(acceleration), 2 * _lg(rate), lg_g) + _LOG4)


@njit(**_LEAN)
def status(q, qd, qdd, present, plan):
    """The verdict on ``q`` and the given ``qd``, ``qdd`` (``present``: :data:`QD`, :data:`QDD`) for
    the mechanism of ``plan`` (:func:`plan`): :data:`OK`, :data:`CONVERT`, :data:`NONFINITE`,
    :data:`NEGATIVE` or :data:`BOUND` (module docstring)."""
    dof, n = plan[0], plan[1]
    if not _c_ordered(q, dof):
        return CONVERT
    if present & QD and not (qd.shape == q.shape and _c_ordered(qd, dof)):
        return CONVERT
    if present & QDD and not (qdd.shape == q.shape and _c_ordered(qdd, dof)):
        return CONVERT
    bq = _int64_view(q)
    top, signs = _scan_q(bq, dof, n, plan[HEAD:])
    rate = _magnitude(_int64_view(qd)) if present & QD else 0
    acceleration = _magnitude(_int64_view(qdd)) if present & QDD else 0
    if top >= _INF or rate >= _INF or acceleration >= _INF:
        return NONFINITE
    if signs < 0 and _lengths(bq, dof, n)[1] > 0:
        return NEGATIVE
    r, a = _float_of(rate), _float_of(acceleration)
    base, lg_g, limit = _float_of(plan[2]), _float_of(plan[3]), _float_of(plan[4])
    if _scale(_float_of(top), r, a, base, lg_g) < limit - MARGIN:
        return OK
    return OK if _scale(_float_of(_lengths(bq, dof, n)[0]), r, a, base, lg_g) < limit else BOUND


@njit(**JIT)
def locate(q, qd, qdd, present, dof, n):
    """``(problem, array, sample, coordinate)`` of the first problem of 2-D ``q, qd, qdd`` (their
    sample counts may differ): the first non-finite entry of ``q`` (array 0), ``qd`` (1), ``qdd`` (2),
    row by row, else the first negative length of ``q``; ``(OK, -1, -1, -1)`` if neither."""
    for k in range(3):
        if k and not present & k:
            continue
        a = q if k == 0 else (qd if k == 1 else qdd)
        for s in range(a.shape[0]):
            for c in range(a.shape[1]):
                if not np.isfinite(a[s, c]):
                    return NONFINITE, k, s, c
    for s in range(q.shape[0]):
        for c in range(dof - n, dof):
            if q[s, c] < 0:
                return NEGATIVE, 0, s, c
    return OK, -1, -1, -1


# --------------------------------------------------------------------------- the numpy reference
def _reference_c_ordered(a: np.ndarray, dof: int) -> bool:
    return (
        a.shape[-1] == dof
        and a.ctypes.data % 8 == 0
        and (a.size == 0 or (a.strides[-1] == 8 and (a.ndim == 1 or a.shape[0] == 1 or a.strides[0] == 8 * dof)))
    )


def plan(dof: int, n: int, base: float, lg_g: float, limit: float) -> np.ndarray:
    """What :func:`status` needs of a mechanism, in one int64 array (one argument to unbox): ``dof``,
    ``n``, the bits of ``base``, ``lg_g`` and ``limit`` (:class:`~exo_bench.models.states.StateCheck`),
    then the column mask of :func:`_scan_q` (-1 on the last ``n`` of every ``dof`` columns, ``ROWS`` rows)."""
    mask = np.zeros((ROWS, dof), np.int64)
    mask[:, dof - n :] = -1
    floats = np.array([base, lg_g, limit]).view(np.int64)
    return np.concatenate([[dof, n], floats, mask.ravel()]).astype(np.int64)


def reference_status(q, qd, qdd, present: int, plan: np.ndarray) -> int:
    """:func:`status` in numpy: the checks as ``as_states`` made them before the compiled pass."""
    dof, n = int(plan[0]), int(plan[1])
    base, lg_g, limit = (float(x) for x in plan[2:HEAD].view(np.float64))
    given = [q] + [a for bit, a in ((QD, qd), (QDD, qdd)) if present & bit]
    if not all(a.shape == q.shape and _reference_c_ordered(a, dof) for a in given):
        return CONVERT
    if not all(np.isfinite(a).all() for a in given):
        return NONFINITE
    lengths = q.reshape(-1, dof)[:, dof - n :]
    if (lengths < 0).any():
        return NEGATIVE
    length, rate, acceleration = (
        max(0.0, float(np.abs(a).max())) if a is not None and a.size else 0.0
        for a in (lengths, qd if present & QD else None, qdd if present & QDD else None)
    )
    return OK if force_scale_from(base, lg_g, length, rate, acceleration) < limit else BOUND


def reference_locate(q, qd, qdd, present: int, dof: int, n: int) -> tuple[int, int, int, int]:
    """:func:`locate` in numpy."""
    for k, a in enumerate((q, qd, qdd)):
        if k and not present & k:
            continue
        bad = np.argwhere(~np.isfinite(a))
        if len(bad):
            return NONFINITE, k, int(bad[0][0]), int(bad[0][1])
    bad = np.argwhere(q[:, dof - n :] < 0)
    if len(bad):
        return NEGATIVE, 0, int(bad[0][0]), dof - n + int(bad[0][1])
    return OK, -1, -1, -1


# --------------------------------------------------------------------------- entry points
class Entries(NamedTuple):
    """The compiled entry points (or the numpy reference): ``status`` for 1-D and for 2-D arrays,
    ``locate`` for 2-D arrays."""

    status_1d: Callable[..., int]
    status_2d: Callable[..., int]
    locate: Callable[..., tuple[int, int, int, int]]


def _array(ndim: int) -> Any:
    return types.Array(types.float64, ndim, "A")


_CONSTANTS = (types.int64, types.int64, types.int64)


@functools.cache
def entries() -> Entries:
    """The pass's entry points, compiled (or loaded from the cache) on the first call in a process."""
    if jit_disabled():
        return Entries(reference_status, reference_status, reference_locate)
    one, two, plans = _array(1), _array(2), types.Array(types.int64, 1, "C")
    return Entries(
        status.compile((one, one, one, types.int64, plans)),
        status.compile((two, two, two, types.int64, plans)),
        locate.compile((two, two, two, *_CONSTANTS)),
    )


_F8 = np.dtype(np.float64)


def _arguments(arrays) -> tuple:
    q, qd, qdd = arrays
    present = (QD if qd is not None else 0) | (QDD if qdd is not None else 0)
    return q, q if qd is None else qd, q if qdd is None else qdd, present


def verdict(check, arrays, reference: bool = False) -> int:
    """:func:`status` of ``arrays = (q, qd or None, qdd or None)`` for ``check`` (a
    :class:`~exo_bench.models.states.StateCheck`): :data:`CONVERT` for anything but float64 ndarrays of
    one dimension count, 1 or 2 (what unboxing trusts)."""
    q, qd, qdd, present = _arguments(arrays)
    if not all(isinstance(a, np.ndarray) and a.dtype == _F8 and a.ndim == q.ndim in (1, 2) for a in (q, qd, qdd)):
        return CONVERT
    by_ndim = check.by_ndim or check.resolve()
    fn = reference_status if reference else by_ndim[q.ndim]
    return fn(q, qd, qdd, present, check.plan)


def first_problem(check, arrays, reference: bool = False) -> tuple[int, int, int, int]:
    """:func:`locate` of ``arrays = (q, qd or None, qdd or None)``, float64 arrays that passed
    :func:`verdict`'s layout (a 1-D array is one sample); sample counts may differ."""
    q, qd, qdd, present = _arguments(arrays)
    two = [a.reshape(1, -1) if a.ndim == 1 else a for a in (q, qd, qdd)]
    fn = reference_locate if reference else entries().locate
    code, k, s, c = fn(two[0], two[1], two[2], present, check.dof, check.nlinks)
    return int(code), int(k), int(s), int(c)
