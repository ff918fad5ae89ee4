"""Streaming stores of the derivatives' output rows: each row of ``dtau/dq``, ``dtau/dqd`` and ``M`` is
written past the caches (non-temporal stores), for batches whose output is larger than the caches.

**Why.** The per-sample kernel (:mod:`.derivatives_compiled`) computes an output row from arrays that
stay in L1 (``Y``, ``mu``), so a large batch is bound by writing its output: chain 100 in 3D writes
2.16 MB per sample. An ordinary store first reads the cache line it writes (read for ownership): the
memory carries every byte twice. A non-temporal store sends whole lines to memory without reading them.
Measured on this 2-core host (load about 8, best of 10, a 134 MB batch of 300 x 300 rows computed as
the kernel does): ordinary stores 0.20-0.30 ms per 720 kB, numpy's ``fill`` 0.12-0.18, these stores
0.071. Results in cache are different: a later read of a streamed row comes from memory, so only
batches of at least :data:`STREAM_MIN_BYTES` of output stream (:func:`streams`).

**How.** The kernel computes each output row as before, into a scratch row in L1 (the same loop, the
same bits), and :func:`stream_row` copies it out. numba has no non-temporal store; :func:`stream_row` is
an intrinsic (``numba.extending.intrinsic``, LLVM IR by llvmlite) that loads 4 (or 2) entries at a time and
stores them with LLVM's ``!nontemporal`` hint (``movntpd`` on x86). The store is declared 16-byte aligned, so
:func:`streams` admits only outputs whose rows all start 16-byte aligned (an even ``dof`` and
16-aligned bases); anything else takes the ordinary loop. :func:`store_fence` (``fence seq_cst``,
``mfence`` on x86) orders the streamed stores before the kernel returns: non-temporal stores are weakly
ordered, and another thread may read the output next.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from exo_bench.models.machine.numba_runtime import JIT, ensure

ensure()  # numba's runtime set-up, before the kernels below are defined

#: A call whose output takes at least this many bytes streams its rows: half of this host's 32 MiB
#: L3; a smaller output stays in cache for the caller's next read (exo5-3d, 256 samples: 0.17 MB).
STREAM_MIN_BYTES = 2**24
_ALIGN = 16  # bytes: the alignment the vector store declares (two float64)


def _vector_copy(context, builder, vty, src, dst, at):
    """Lanes ``at ..`` of ``src`` stored non-temporally at ``dst``'s ``at ..`` (pointers to float64)."""
    value = builder.load(builder.bitcast(builder.gep(src, [at]), vty.as_pointer()), align=8)
    store = builder.store(value, builder.bitcast(builder.gep(dst, [at]), vty.as_pointer()), align=_ALIGN)
    store.set_metadata("nontemporal", builder.module.add_metadata([ir.Constant(ir.IntType(32), 1)]))


@intrinsic
def stream_row(typingctx, out, start, a):
    """``out.flat[start : start + len(a)] = a`` by streaming stores, in blocks of 4 and one of 2: ``out``
    C-contiguous with that entry 16-byte aligned, ``len(a)`` even (:func:`streams`). One loop in LLVM IR,
    no call: a call of a compiled function per row would count references to its array arguments by
    atomic (locked) instructions, and a locked instruction drains the write-combining buffers, half a
    cache line at a time (measured: 2.5 ms per sample instead of 0.95 on chain 100 3D)."""

    def codegen(context, builder, signature, args):
        oty, _, aty = signature.args
        dst = builder.gep(context.make_array(oty)(context, builder, args[0]).data, [args[1]])
        src_ary = context.make_array(aty)(context, builder, args[2])
        n = cgutils.unpack_tuple(builder, src_ary.shape, 1)[0]
        intp = n.type
        blocks = builder.sdiv(n, ir.Constant(intp, 4))
        v4, v2 = ir.VectorType(ir.DoubleType(), 4), ir.VectorType(ir.DoubleType(), 2)
        with cgutils.for_range(builder, blocks) as loop:
            _vector_copy(context, builder, v4, src_ary.data, dst, builder.mul(loop.index, ir.Constant(intp, 4)))
        done = builder.mul(blocks, ir.Constant(intp, 4))
        with builder.if_then(builder.icmp_signed("<", done, n)):
            _vector_copy(context, builder, v2, src_ary.data, dst, done)
        return context.get_dummy_value()

    return types.void(out, types.intp, a), codegen


@intrinsic
def _fence(typingctx):
    def codegen(context, builder, signature, args):
        builder.fence("seq_cst")
        return context.get_dummy_value()

    return types.void(), codegen


@njit(**JIT)
def store_fence():
    """Order every streamed store before what follows (module docstring)."""
    _fence()


def streams(outs: tuple[np.ndarray, ...], dof: int) -> bool:
    """Whether a call writing ``outs`` (C-contiguous float64, rows of ``dof``) streams its rows: at least
    :data:`STREAM_MIN_BYTES` of output, every row 16-byte aligned (even ``dof``, aligned bases), and
    compiled kernels (an intrinsic has no Python form under ``NUMBA_DISABLE_JIT``)."""
    from exo_bench.models.machine.numba_runtime import jit_disabled

    if dof % 2 or sum(o.nbytes for o in outs) < STREAM_MIN_BYTES or jit_disabled():
        return False
    return all(o.ctypes.data % _ALIGN == 0 for o in outs)
