"""The output rows of one link of the analytic derivatives, as explicit 4-wide SIMD code: numba intrinsics
(LLVM IR written here) used by :func:`exo_bench.models.newton_euler.derivatives_compiled._blocks`.

For row link ``i`` the ``dim`` rows ``r_c = c n + i`` (``c < dim``) of one output are ``o[r_c, k] = m[k] *
(z_c0 Y[e, k] + z_c1 Y[e + 1, k] (+ z_c2 Y[e + 2, k]))`` (``z_cu``: component ``u`` of column ``c`` of ``s_i
J_i``; ``m``: row ``i`` of ``mu`` repeated; ``Y[e..]``: the signed columns of one kind). :func:`rows_3d` and
:func:`rows_2d` write them in one loop over 4 columns at a time, each load of ``m`` and ``Y`` shared by the
``dim`` rows, the last 4 columns overlapping the previous ones when ``dof`` is not a multiple of 4 (the
same values written twice; the outputs never overlap ``m`` or ``Y``, which are the kernel's scratch), and a
loop of one column at a time when ``dof < 4``.

**Why not a numba loop.** Written as ``for k in range(dof)`` per row, LLVM vectorises each row with a
16-wide main body (4 vectors interleaved), a 4-wide remainder loop, scalar leftovers and a runtime
check that the output row does not alias ``m`` and ``Y`` (numba cannot tell LLVM that arrays are apart):
at exo5-3d's rows of 15 the main body never runs and the checks and leftovers cost more than the
arithmetic. numba leaves LLVM's SLP vectoriser off, so four columns written out by hand stay scalar. Here:
exo5-3d, 256 samples, one thread (CPU of the blocks alone, load 8): 0.54 us per sample by the numba
loops, 0.38 by these rows.

The same operations in the same order as the loops (``m * ((z0 y0 + z1 y1) + z2 y2)``, IEEE products and
sums, no fused multiply-add): the same bits. Under ``NUMBA_DISABLE_JIT`` (an intrinsic has no Python form)
:data:`rows_3d` and :data:`rows_2d` are those loops in Python (:func:`rows_python`).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from exo_bench.models.machine.numba_runtime import jit_disabled

_I32, _I64 = ir.IntType(32), ir.IntType(64)
_V4 = ir.VectorType(ir.DoubleType(), 4)
_W = 4  # columns per step


def _splat(b, x):
    v = b.insert_element(ir.Constant(_V4, None), x, ir.Constant(_I32, 0))
    return b.shuffle_vector(v, v, ir.Constant(ir.VectorType(_I32, _W), [0] * _W))


def _combine(b, mk, ys, zs):
    """``mk * ((z0 y0 + z1 y1) + z2 y2)``, in the loops' order (scalars or vectors alike)."""
    acc = b.fmul(zs[0], ys[0])
    for y, z in zip(ys[1:], zs[1:]):
        acc = b.fadd(acc, b.fmul(z, y))
    return b.fmul(mk, acc)


def _codegen(dim: int):
    """The code of :func:`rows_3d` (``dim = 3``) or :func:`rows_2d`: arguments ``(o, i, m, Y, n, e, z...)``,
    ``z[c dim + u]`` component ``u`` of column ``c``."""

    def codegen(context, b, sig, args):
        o, m, Y = (context.make_array(sig.args[k])(context, b, args[k]) for k in (0, 2, 3))
        i, n, e, z = args[1], args[4], args[5], args[6 : 6 + dim * dim]
        ncol = cgutils.unpack_tuple(b, o.shape, 2)[1]
        ystride = cgutils.unpack_tuple(b, Y.shape, 2)[1]
        const = lambda v: ir.Constant(_I64, v)  # noqa: E731
        dsts = [b.gep(o.data, [b.mul(b.add(b.mul(const(c), n), i), ncol)]) for c in range(dim)]
        rows = [b.gep(Y.data, [b.mul(b.add(e, const(u)), ystride)]) for u in range(dim)]

        def step(k, load, zs):
            ys = [load(p, k) for p in rows]
            mk = load(m.data, k)
            return [_combine(b, mk, ys, zs[c * dim : (c + 1) * dim]) for c in range(dim)]

        def vector_at(p, k):
            return b.bitcast(b.gep(p, [k]), _V4.as_pointer())

        with b.if_else(b.icmp_signed(">=", ncol, const(_W))) as (wide, narrow):
            with wide:
                zv = [_splat(b, x) for x in z]
                last = b.sub(ncol, const(_W))
                with cgutils.for_range(b, b.sdiv(b.add(ncol, const(_W - 1)), const(_W))) as loop:
                    k = b.mul(loop.index, const(_W))
                    k = b.select(b.icmp_signed(">", k, last), last, k)
                    for dst, v in zip(dsts, step(k, lambda p, k: b.load(vector_at(p, k), align=8), zv)):
                        b.store(v, vector_at(dst, k), align=8)
            with narrow:
                with cgutils.for_range(b, ncol) as loop:
                    k = loop.index
                    for dst, v in zip(dsts, step(k, lambda p, k: b.load(b.gep(p, [k])), z)):
                        b.store(v, b.gep(dst, [k]))
        return context.get_dummy_value()

    return codegen


@intrinsic
def _rows_3d(typingctx, o, i, m, Y, n, e, z00, z01, z02, z10, z11, z12, z20, z21, z22):
    sig = types.void(o, i, m, Y, n, e, z00, z01, z02, z10, z11, z12, z20, z21, z22)
    return sig, _codegen(3)


@intrinsic
def _rows_2d(typingctx, o, i, m, Y, n, e, z00, z01, z10, z11):
    return types.void(o, i, m, Y, n, e, z00, z01, z10, z11), _codegen(2)


def rows_python(o, i, m, Y, n, e, *z) -> None:
    """The rows as the numba loops wrote them (module docstring), for ``NUMBA_DISABLE_JIT``."""
    dim = 3 if len(z) == 9 else 2
    for c in range(dim):
        r = c * n + i
        for k in range(o.shape[1]):
            acc = z[c * dim] * Y[e, k] + z[c * dim + 1] * Y[e + 1, k]
            if dim == 3:
                acc = acc + z[c * dim + 2] * Y[e + 2, k]
            o[r, k] = m[k] * acc


#: ``rows_3d(o, i, m, Y, n, e, z00, z01, z02, z10, ..., z22)`` and ``rows_2d(o, i, m, Y, n, e, z00, z01,
#: z10, z11)``: the intrinsics, or :func:`rows_python` under ``NUMBA_DISABLE_JIT`` (fixed at import).
rows_3d = rows_python if jit_disabled() else _rows_3d
rows_2d = rows_python if jit_disabled() else _rows_2d
