"""Method ``newton-euler``, compiled to vectorise across samples: the batched inverse dynamics.

The per-sample kernel (:mod:`exo_bench.models.newton_euler.compiled`) computes each sample whole,
with libm's ``sin`` and ``cos`` per angle (four calls per 3D rod, most of its time): nothing is
vectorised. This kernel computes :data:`LANES` samples at once, each step a loop over the samples
that LLVM turns into SIMD instructions, in the layout of :mod:`exo_bench.models.machine.simd_blocks` (shared
with ``matrix-factored``'s :mod:`exo_bench.matrix_method.numba_kernels.simd`):

1. **transpose in** a block of the user's flat ``(samples, dof)`` states into per-link rows of ``W``
   (:func:`exo_bench.models.machine.simd_blocks.block_transposes`: tiles of 8 x 8 through SIMD registers for a
   whole block; 3D chains of n = 5, 100, 1000, one thread, the quiet machine: 68, 1548 and 16,800 ns
   per sample against 88, 1778 and 20,300 with the loops alone);
2. **forward pass, roots first**, one loop over the samples per link ``k``: ``sin``/``cos`` of its
   angles in branch-free arithmetic (:func:`exo_bench.models.machine.fast_trig.sincos_reduced`), the rod's
   ``kappa_k = s_k (l u)''`` (:func:`exo_bench.models.mechanism.rod_elements.rod_acceleration_3d`), its
   start point's acceleration with gravity ``A_k = A_p + kappa_p`` (``g up`` at a root) and ``D_k =
   0``. The angles of link ``k`` beyond the arithmetic's range (and NaN) are then redone with libm
   by a scalar loop that only they enter, before any child reads ``kappa_k``. The trig loops are
   ``matrix-factored``'s too (:mod:`exo_bench.models.machine.simd_blocks`); one source serves 2D and 3D
   (``forward_for(dim)`` in :func:`build`, ``dim`` a constant of its closure);
3. **backward pass, leaves first**: ``f_k = eta A_k + zeta kappa_k + D_k``, ``D_p += theta A_k + eta
   kappa_k + D_k``, ``tau_k = s_k J_k^T f_k`` (:func:`exo_bench.models.mechanism.rod_elements.project_3d`),
   written over ``A_k`` (no longer read);
4. **transpose out** into the user's ``(samples, dof)`` result (the same tiles, the other way).

Rows of ``F`` per link: ``D`` in ``F0..F2``, ``A`` and then ``tau`` in ``O0..O2``. The physics is the
element functions the per-sample kernel calls, with the same operations in the same order: the
result differs from that kernel's only by the ``sin``/``cos`` (within :data:`~exo_bench.models.machine.fast_trig.ULPS` ulp each,
:mod:`exo_bench.models.machine.fast_trig`); where an angle falls back to libm the two are identical.

Reading each link's states straight from the user's arrays inside the forward pass (strided
loads, no transpose in) was tried and measured 0.79-0.87x as fast at 3D n = 5, 20, 100 and 1.12x at
n = 1000 (the shared machine, load 3.7): the transposes stay.

The functions are built by :func:`build` for a block size that numba compiles in as a constant:
blocks of :data:`LANES` samples, or :data:`NARROW_LANES` for mechanisms of at least
:data:`NARROW_FROM_LINKS` links (:func:`kernel_for`, chosen at prepare time).

**Whole blocks** run :func:`_block` with the block size itself as ``m``: numba compiles ``_block``
once, LLVM inlines it at both call sites, and in the whole-block one every loop over the samples
has the constant trip count (no remainder loop, no runtime checks): 3D chains of n = 5 and 100 took
0.094 and 2.08 us per sample against 0.124 and 2.56 with ``m`` at run time (one thread, the other
core running the benchmark sweep). The last, partial block runs the same function with ``m`` at
run time.

**Prefetch.** The user's states are read at a stride of ``dof`` doubles (one cache line per sample
and link block), which the hardware prefetchers do not follow far enough: a batch larger than L2
(2 MiB here) took 23 ns per link and sample at n = 100 against 13 in cache. During its forward
pass each block asks for the next block's lines, one share per link
(:func:`exo_bench.models.machine.simd_blocks.prefetch_share`, LLVM's ``llvm.prefetch``): n = 100, 1024
samples (9.8 MB) 23.1 -> 15.3 ns, 4096 (39 MB) 23.9 -> 20.4, n = 1000, 256 samples 28.8 -> 20.5;
in cache 12.9 -> 13.1 (same conditions).

One sample as 1-D arrays runs the per-sample kernel (with ``check=True`` too); every batch (:data:`MIN_SAMPLES`) runs this
kernel through :func:`exo_bench.models.machine.simd_blocks.run` (threads without numba's threading layer).
numba's on-disk cache of these kernels is keyed on their folder, the element functions' files and
the shared ``fast_trig.py``, ``simd_*.py`` and ``numba_runtime.py`` (:mod:`exo_bench.models.machine.numba_cache`):
an edit to any of them recompiles them.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from numba.extending import register_jitable

from exo_bench.models.machine import simd_blocks
from exo_bench.models.machine import numba_cache
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.machine.numba_runtime import jit_for
from exo_bench.models.machine.simd_blocks import states_2d, states_3d
from exo_bench.models.machine.simd_blocks import CF, CP, F0, F1, F2, FROWS, K0, K1, K2, LANES, LEN, LEN2, O0, O1, O2
from exo_bench.models.machine.simd_blocks import ROWS, SF, SP, block_transposes, prefetch_share

numba_cache.inline(el.ELEMENTS, Path(__file__).parent)  # registered once, keyed on rod_elements.py


#: Rows of the per-mechanism table (:meth:`exo_bench.models.newton_euler.passes.Tree.table`) read here.
_PARENT, _SIGN, _ZETA, _ETA, _THETA = range(5)

#: Batches of at least this many samples run this kernel: every ``(samples, dof)`` batch, as
#: ``matrix-factored``'s does; a 1-D single sample runs the per-sample kernel. A larger threshold
#: would be faster for 2-7 samples (this kernel took 1.2-2.0x the per-sample kernel's time at 1-6
#: samples and 0.5-0.8x at 8-32: its vectorised loops take 8 samples a step; exo5 2D and 3D, 3D
#: chain of 100, the shared machine at load 3.5), but the result would then depend on how a batch
#: is cut into chunks (tests/test_resources.py holds chunks to the bit), since the two kernels' sin
#: and cos differ by up to 2 ulp. The per-sample kernel with the arithmetic sin/cos was
#: bit-identical to this one but 1.5-1.9x slower than with libm's (inverse and forward, exo5-3d and
#: 3D n = 100), so it keeps libm's.
MIN_SAMPLES = 1


@register_jitable
def _rod_3d(W, at, B, s_k, cf, sf, cp, sp):
    """2. ``kappa_k = s_k (l u)''`` of sample ``at`` of a spatial rod (the ``link`` of
    :func:`exo_bench.models.machine.simd_blocks.link_pass`)."""
    l, w, v, ld, wdd, vdd, ldd = states_3d(W, at, B)
    a0, a1, a2 = el.rod_acceleration_3d(cf, sf, cp, sp, l, w, v, ld, wdd, vdd, ldd)
    W[at + K0 * B], W[at + K1 * B], W[at + K2 * B] = s_k * a0, s_k * a1, s_k * a2


@register_jitable
def _rod_2d(W, at, B, s_k, cf, sf, cp, sp):
    """2. ``kappa_k`` of sample ``at`` of a planar rod (phi in row 0, l in row 1; the third component 0)."""
    l, w, ld, wdd, ldd = states_2d(W, at, B)
    a0, a1 = el.rod_acceleration_2d(cf, sf, l, w, ld, wdd, ldd)
    W[at + K0 * B], W[at + K1 * B], W[at + K2 * B] = s_k * a0, s_k * a1, 0.0


def _jit(lanes: int, dim: int):
    """:func:`exo_bench.models.machine.numba_runtime.jit_for` for a closure built for ``dim`` too: its qualified
    name carries both (``..._forward_3d_32lanes``), for the reason given there."""

    def decorate(fn):
        fn.__qualname__ = f"{fn.__qualname__}_{dim}d"
        return jit_for(lanes)(fn)

    return decorate


def build(lanes: int) -> SimpleNamespace:
    """The kernel's functions compiled for blocks of ``lanes`` samples (numba freezes ``lanes`` as a
    constant: a runtime block size left the loops scalar, 2.5-3x slower); :func:`kernel_for` picks
    the block size for a mechanism."""
    B = lanes
    scratch, rows_in, rows_out = block_transposes(lanes)

    @jit_for(lanes)
    def _start_points(t, g, dim, k, m, W, F):
        """2. (end) ``A_k = A_p + kappa_p`` (``g up`` at a root) into ``O0..O2`` of link ``k``, ``D_k = 0``.

        The loops index per-link views (``Fk``, ``Fp``, ``Wp``): with the offsets of links ``k`` and ``p``
        folded into the views' pointers LLVM vectorises them (indexing the whole arrays at runtime
        offsets, it did not, measured with ``inspect_asm``)."""
        Fk = F[k * FROWS * B : (k + 1) * FROWS * B]
        p = int(t[_PARENT, k])
        if p >= 0:
            Fp, Wp = F[p * FROWS * B : (p + 1) * FROWS * B], W[p * ROWS * B : (p + 1) * ROWS * B]
            for s in range(m):
                Fk[O0 * B + s] = Fp[O0 * B + s] + Wp[K0 * B + s]
                Fk[O1 * B + s] = Fp[O1 * B + s] + Wp[K1 * B + s]
                Fk[O2 * B + s] = Fp[O2 * B + s] + Wp[K2 * B + s]
                Fk[F0 * B + s], Fk[F1 * B + s], Fk[F2 * B + s] = 0.0, 0.0, 0.0
        else:
            up1, up2 = (g, 0.0) if dim == 2 else (0.0, g)
            for s in range(m):
                Fk[O0 * B + s], Fk[O1 * B + s], Fk[O2 * B + s] = 0.0, up1, up2
                Fk[F0 * B + s], Fk[F1 * B + s], Fk[F2 * B + s] = 0.0, 0.0, 0.0

    @jit_for(lanes)
    def _backward(t, dim, m, W, F):
        """3. The backward pass of ``m`` samples: ``D_p += ...``, then ``f_k``, then ``tau_k`` over ``A_k``
        (3D: the ``F0..F2`` and ``O0..O2`` rows all used; 2D: the first two of each). Per-link views as
        in :func:`_start_points`."""
        n = t.shape[1]
        for k in range(n - 1, -1, -1):
            Wk, Fk = W[k * ROWS * B : (k + 1) * ROWS * B], F[k * FROWS * B : (k + 1) * FROWS * B]
            zeta, eta, theta, s_k = t[_ZETA, k], t[_ETA, k], t[_THETA, k], t[_SIGN, k]
            p = int(t[_PARENT, k])
            if p >= 0:
                Fp = F[p * FROWS * B : (p + 1) * FROWS * B]
                for s in range(m):
                    Fp[F0 * B + s] += el.subtree_share(theta, eta, Fk[O0 * B + s], Wk[K0 * B + s], Fk[F0 * B + s])
                    Fp[F1 * B + s] += el.subtree_share(theta, eta, Fk[O1 * B + s], Wk[K1 * B + s], Fk[F1 * B + s])
                    Fp[F2 * B + s] += el.subtree_share(theta, eta, Fk[O2 * B + s], Wk[K2 * B + s], Fk[F2 * B + s])
            if dim == 3:
                for s in range(m):
                    f0 = el.rod_force(zeta, eta, Fk[O0 * B + s], Wk[K0 * B + s], Fk[F0 * B + s])
                    f1 = el.rod_force(zeta, eta, Fk[O1 * B + s], Wk[K1 * B + s], Fk[F1 * B + s])
                    f2 = el.rod_force(zeta, eta, Fk[O2 * B + s], Wk[K2 * B + s], Fk[F2 * B + s])
                    m0, m1, m2 = el.project_3d(
                        Wk[CF * B + s], Wk[SF * B + s], Wk[CP * B + s], Wk[SP * B + s], Wk[LEN * B + s], f0, f1, f2
                    )
                    Fk[O0 * B + s], Fk[O1 * B + s], Fk[O2 * B + s] = s_k * m0, s_k * m1, s_k * m2
            else:
                for s in range(m):
                    f0 = el.rod_force(zeta, eta, Fk[O0 * B + s], Wk[K0 * B + s], Fk[F0 * B + s])
                    f1 = el.rod_force(zeta, eta, Fk[O1 * B + s], Wk[K1 * B + s], Fk[F1 * B + s])
                    m0, m1 = el.project_2d(Wk[CF * B + s], Wk[SF * B + s], Wk[LEN2 * B + s], f0, f1)
                    Fk[O0 * B + s], Fk[O1 * B + s] = s_k * m0, s_k * m1

    link_pass, libm_pass = simd_blocks.link_pass, simd_blocks.libm_pass

    def forward_for(dim):
        rod = _rod_3d if dim == 3 else _rod_2d

        @_jit(lanes, dim)
        def _forward(t, g, m, W, F, q, qd, qdd, o, lo, hi):
            """2. The forward pass of ``m`` samples: per link, trig and ``kappa`` (libm for the angles
            beyond RANGE, before any child reads ``kappa``), then its start point."""
            n = t.shape[1]
            for k in range(n):
                w, s_k = k * ROWS * B, t[_SIGN, k]
                if link_pass(W, w, m, B, dim, rod, s_k):
                    libm_pass(W, w, m, B, dim, rod, s_k)
                _start_points(t, g, dim, k, m, W, F)
                prefetch_share(q, qd, qdd, o, lo, hi, k, n)

        return _forward

    _forward_2d, _forward_3d = forward_for(2), forward_for(3)

    @jit_for(lanes)
    def _block(t, g, dim, q, qd, qdd, o, s0, m, n, W, F, T, stop):
        """1-4 for the ``m`` samples from ``s0``; the next block's lines prefetched during the forward pass."""
        rows_in(q, qd, qdd, s0, m, n, dim, W, T)
        lo, hi = (s0 + m) * dim * n, min(stop, s0 + m + B) * dim * n
        if dim == 3:
            _forward_3d(t, g, m, W, F, q, qd, qdd, o, lo, hi)
        else:
            _forward_2d(t, g, m, W, F, q, qd, qdd, o, lo, hi)
        _backward(t, dim, m, W, F)
        rows_out(o, s0, m, n, dim, F, T)

    @jit_for(lanes)
    def simd_inverse(p, q, qd, qdd, o, start, stop, S=None):
        """Inverse dynamics of samples ``start .. stop - 1`` of the flat ``(samples, dof)`` states into
        ``o``, :data:`LANES` (or ``lanes``) at a time; ``p = (table, g, dim)``; ``S``: the scratch
        ``(W, F, T)`` of ``scratch(n, dim)`` (:class:`exo_bench.models.machine.simd_blocks.ThreadScratch`), or
        None to allocate it here."""
        t, g, dim = p
        n = t.shape[1]
        if S is None:
            W, F, T = scratch(n, dim)
        else:
            W, F, T = S
        for s0 in range(start, stop, B):
            if stop - s0 >= B:  # a whole block: the trip counts are the constant B (module docstring)
                _block(t, g, dim, q, qd, qdd, o, s0, B, n, W, F, T, stop)
            else:
                _block(t, g, dim, q, qd, qdd, o, s0, stop - s0, n, W, F, T, stop)

    return SimpleNamespace(
        lanes=lanes,
        _start_points=_start_points,
        _backward=_backward,
        _forward_3d=_forward_3d,
        _forward_2d=_forward_2d,
        _block=_block,
        simd_inverse=simd_inverse,
        scratch=scratch,
    )


_WIDE = build(LANES)
_start_points, _backward, _forward_3d, _forward_2d = (
    _WIDE._start_points,
    _WIDE._backward,
    _WIDE._forward_3d,
    _WIDE._forward_2d,
)
simd_inverse = _WIDE.simd_inverse

#: Blocks of this many samples for mechanisms of at least :data:`NARROW_FROM_LINKS` links.
NARROW_LANES = 16
#: From this many links on, blocks of :data:`NARROW_LANES` samples: the scratch of 32-sample blocks
#: (22 rows of 32 doubles per link, 5.5 MB at n = 1000) is far beyond L2 (1 MiB per core here) and
#: the transposes read 3 x 32 sample rows at once. 16-sample blocks against 32 on 3D chains (per
#: sample, one thread, best of 7 interleaved; the shared 2-core machine, load 1.1-1.6): n = 1000
#: 0.86-1.00x (median 0.95x over 16 runs), n = 100-700 0.97-1.02x, n = 20 1.17-1.24x; 8-sample
#: blocks were slower at every n (1.05-1.4x). The growth exponent from n = 20 to 1000 falls by
#: about 0.01 only (1.04-1.06 in these runs): most of the growth is elsewhere.
NARROW_FROM_LINKS = 800
_NARROW = build(NARROW_LANES)


def blocks_for(nlinks: int) -> SimpleNamespace:
    """The :func:`build` for a mechanism of ``nlinks`` links: blocks of :data:`LANES` samples, or from
    :data:`NARROW_FROM_LINKS` links on blocks of :data:`NARROW_LANES`; its ``simd_inverse`` is the
    batched kernel and its ``scratch(n, blocks)`` that kernel's scratch."""
    return _NARROW if nlinks >= NARROW_FROM_LINKS else _WIDE


def kernel_for(nlinks: int):
    """The batched kernel ``(p, q, qd, qdd, o, start, stop)`` for a mechanism of ``nlinks`` links:
    :func:`simd_inverse` (blocks of :data:`LANES`), or from :data:`NARROW_FROM_LINKS` links on the same
    kernel compiled for blocks of :data:`NARROW_LANES` (:func:`blocks_for`)."""
    return blocks_for(nlinks).simd_inverse
