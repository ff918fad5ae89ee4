"""8 x 8 transposes of doubles in SIMD registers, as numba intrinsics (LLVM IR written here).

The kernels that vectorise across samples (:mod:`exo_bench.models.machine.simd_blocks`) move each block of
the user's ``(samples, dof)`` states into per-link rows of samples and the results back. Written as
loops over the samples, the move in reads a column of the states (stride ``dof``): LLVM makes it a
``vgatherqpd`` per 8 samples, which Zen 4 runs at several cycles each, and the move out stores one
double at a time. Here 8 samples x 8 columns move as 8 vector loads, 24 shuffles (the classic
three-stage network: pairs of doubles, pairs of 128-bit halves, 256-bit halves) and 8 vector
stores. The columns past the last (``rem < 8``) are masked: ``llvm.masked.load`` and
``llvm.masked.store`` neither read nor write them (no fault at the end of an array).

Pure data movement: the results are the same bits as the loops'.

* :func:`tile_in` ``(src, base, stride, rem, dst, offs, c0, add)``: rows ``r = 0..7`` of ``src``
  at ``base + r * stride``, columns ``0..rem - 1`` of them, go to ``dst[offs[c0 + i] + add + r]``
  (column ``i`` as one vector of 8). ``offs`` has 8 entries from ``c0`` on; those past ``rem`` point
  to a spare row of ``dst`` (they receive the masked, zero lanes).
* :func:`tile_out` ``(src, offs, c0, add, dst, base, stride, rem)``: the other way: vectors
  ``src[offs[c0 + i] + add ..][:8]`` for ``i = 0..7`` (any valid offset past ``rem``: they are not
  stored) go to rows ``r = 0..7`` of ``dst`` at ``base + r * stride``, columns ``0..rem - 1``.

No bounds checks: the callers (:mod:`exo_bench.models.machine.simd_blocks`) pass whole blocks only.
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

#: doubles per SIMD tile side
TILE = 8

_I32, _I64 = ir.IntType(32), ir.IntType(64)
_V = ir.VectorType(ir.DoubleType(), TILE)
_MASK = ir.VectorType(ir.IntType(1), TILE)


def _shuffle(b, x, y, lanes):
    return b.shuffle_vector(x, y, ir.Constant(ir.VectorType(_I32, TILE), lanes))


def transpose_network(b, rows: list) -> list:
    """The 8 columns of the 8 row vectors ``rows`` (IR values): doubles of rows ``2a, 2a + 1``
    interleaved, then pairs of them, then halves."""
    lo, hi = [0, 8, 2, 10, 4, 12, 6, 14], [1, 9, 3, 11, 5, 13, 7, 15]
    t = []
    for a in range(0, TILE, 2):
        t += [_shuffle(b, rows[a], rows[a + 1], lo), _shuffle(b, rows[a], rows[a + 1], hi)]
    pair_lo, pair_hi = [0, 1, 8, 9, 4, 5, 12, 13], [2, 3, 10, 11, 6, 7, 14, 15]
    u = [None] * TILE
    for h in (0, 4):
        u[h], u[h + 2] = _shuffle(b, t[h], t[h + 2], pair_lo), _shuffle(b, t[h], t[h + 2], pair_hi)
        u[h + 1], u[h + 3] = _shuffle(b, t[h + 1], t[h + 3], pair_lo), _shuffle(b, t[h + 1], t[h + 3], pair_hi)
    half_lo, half_hi = [0, 1, 2, 3, 8, 9, 10, 11], [4, 5, 6, 7, 12, 13, 14, 15]
    cols = [None] * TILE
    for i in range(4):
        cols[i], cols[4 + i] = _shuffle(b, u[i], u[4 + i], half_lo), _shuffle(b, u[i], u[4 + i], half_hi)
    return cols


def _mask(b, rem):
    """Lanes ``0..rem - 1`` on."""
    r = b.insert_element(ir.Constant(ir.VectorType(_I64, TILE), None), rem, ir.Constant(_I32, 0))
    r = _shuffle(b, r, r, [0] * TILE)
    return b.icmp_signed("<", ir.Constant(ir.VectorType(_I64, TILE), list(range(TILE))), r)


def _vector_at(b, data, idx):
    return b.bitcast(b.gep(data, [idx]), _V.as_pointer())


def _strided(b, base, stride, r):
    return b.add(base, b.mul(stride, ir.Constant(_I64, r)))


def _offset(b, offs, c0, i, add):
    return b.add(b.load(b.gep(offs, [b.add(c0, ir.Constant(_I64, i))])), add)


def _data(context, b, typ, value):
    return context.make_array(typ)(context, b, value).data


def _tile_move(gather: bool):
    """The code of :func:`tile_in` (``gather``: masked loads of the strided rows of ``src``, stores of
    columns at offsets of ``dst``) or :func:`tile_out` (loads at offsets of ``src``, masked stores
    of rows into ``dst``); both take ``(src, *its address, dst, *its address)``, the strided side's
    address ``(base, stride, rem)``, the offset side's ``(offs, c0, add)``."""

    def codegen(context, b, signature, args):
        src, dst = (_data(context, b, signature.args[k], args[k]) for k in (0, 4))
        at = 5 if gather else 1  # the offset side's arguments, the strided side's the others
        offs_, c0_, add_ = args[at : at + 3]
        base_, stride_, rem_ = args[6 - at : 9 - at]
        o = _data(context, b, signature.args[at], offs_)
        strided, packed = (src, dst) if gather else (dst, src)
        mask, align = _mask(b, rem_), ir.Constant(_I32, 8)
        if gather:
            load = cgutils.get_or_insert_function(
                b.module, ir.FunctionType(_V, [_V.as_pointer(), _I32, _MASK, _V]), "llvm.masked.load.v8f64.p0"
            )
            zero = ir.Constant(_V, None)
            rows = [
                b.call(load, [_vector_at(b, strided, _strided(b, base_, stride_, r)), align, mask, zero])
                for r in range(TILE)
            ]
            for i, col in enumerate(transpose_network(b, rows)):
                b.store(col, _vector_at(b, packed, _offset(b, o, c0_, i, add_)), align=8)
        else:
            store = cgutils.get_or_insert_function(
                b.module,
                ir.FunctionType(ir.VoidType(), [_V, _V.as_pointer(), _I32, _MASK]),
                "llvm.masked.store.v8f64.p0",
            )
            cols = [b.load(_vector_at(b, packed, _offset(b, o, c0_, i, add_)), align=8) for i in range(TILE)]
            for r, row in enumerate(transpose_network(b, cols)):
                b.call(store, [row, _vector_at(b, strided, _strided(b, base_, stride_, r)), align, mask])
        return context.get_dummy_value()

    return codegen


@intrinsic
def tile_in(typingctx, src, base, stride, rem, dst, offs, c0, add):
    return types.void(src, base, stride, rem, dst, offs, c0, add), _tile_move(True)


@intrinsic
def tile_out(typingctx, src, offs, c0, add, dst, base, stride, rem):
    return types.void(src, offs, c0, add, dst, base, stride, rem), _tile_move(False)
