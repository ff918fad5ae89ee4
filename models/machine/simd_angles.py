"""Step 2 of the kernels that vectorise across samples, written once for both families and both dimensions.

Per link, a loop over the samples of a block (:mod:`exo_bench.models.machine.simd_blocks`' layout: the link's
rows of ``W`` start at ``w``, a row is ``B`` samples): ``sin``/``cos`` of the link's angles (``phi``;
in 3D ``psi`` too) in branch-free arithmetic (:func:`exo_bench.models.machine.fast_trig.sincos_reduced`), stored
in the rows ``CF, SF`` (``CP, SP``), then ``link(W, w + s, B, x, cos phi, sin phi, cos psi, sin psi)``:
the family's element step for sample ``s``, which stores the link's ``kappa`` (``x`` is its own number,
the link's sign for newton-euler; it reads the link's states with :func:`states_3d` or :func:`states_2d`).
An angle beyond the arithmetic's range (or NaN) counts as outside: :func:`libm_pass` then redoes its
samples with libm's ``sin``/``cos``, a scalar loop that only they enter.

The kernels (``matrix-factored``'s :mod:`exo_bench.matrix_method.numba_kernels.simd` and
``newton-euler``'s :mod:`exo_bench.models.newton_euler.simd`) pass ``dim`` and ``link`` as constants
of their per-dimension closures. The functions here are inlined into them in numba's IR
(``register_jitable(inline="always")``): the branches on ``dim`` fold away and every loop over the
samples compiles as if written out for its dimension (planar: no ``psi``, no trig of it).
"""

from __future__ import annotations

import math

from numba.extending import register_jitable

from exo_bench.models.machine.fast_trig import RANGE, sincos_reduced
from exo_bench.models.machine.simd_blocks import CF, CP, L1, L1_2, L2, L2_2, LEN, LEN2, PHI, PSI, SF, SP, V1, V2, W1, W2

_inline = register_jitable(inline="always")


@_inline
def link_pass(W, w, m, B, dim, link, x):
    """The ``m`` samples of the link whose rows start at ``w``: fast ``sin``/``cos``, then ``link``;
    the number of angles beyond the range (NaN too), whose samples :func:`libm_pass` redoes."""
    outside = 0
    for s in range(m):
        phi, psi = W[w + PHI * B + s], W[w + PSI * B + s] if dim == 3 else 0.0
        okf, okp = abs(phi) <= RANGE, abs(psi) <= RANGE
        sf, cf = sincos_reduced(phi if okf else 0.0)
        sp, cp = sincos_reduced(psi if okp else 0.0) if dim == 3 else (0.0, 1.0)
        outside += (0 if okf else 1) + (0 if okp else 1)
        W[w + CF * B + s], W[w + SF * B + s] = cf, sf
        if dim == 3:
            W[w + CP * B + s], W[w + SP * B + s] = cp, sp
        link(W, w + s, B, x, cf, sf, cp, sp)
    return outside


@_inline
def libm_pass(W, w, m, B, dim, link, x):
    """The samples of :func:`link_pass`'s link with an angle beyond the range, again with libm's ``sin``/``cos``."""
    for s in range(m):
        phi, psi = W[w + PHI * B + s], W[w + PSI * B + s] if dim == 3 else 0.0
        if not (abs(phi) <= RANGE and abs(psi) <= RANGE):
            cf, sf, cp, sp = math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi)
            W[w + CF * B + s], W[w + SF * B + s] = cf, sf
            if dim == 3:
                W[w + CP * B + s], W[w + SP * B + s] = cp, sp
            link(W, w + s, B, x, cf, sf, cp, sp)


@_inline
def states_3d(W, at, B):
    """Sample ``at`` of a spatial link: ``l, phi', psi', l', phi'', psi'', l''`` (what its ``kappa`` takes)."""
    return (
        W[at + LEN * B],
        W[at + W1 * B],
        W[at + V1 * B],
        W[at + L1 * B],
        W[at + W2 * B],
        W[at + V2 * B],
        W[at + L2 * B],
    )


@_inline
def states_2d(W, at, B):
    """Sample ``at`` of a planar link (phi in row 0, l in row 1): ``l, phi', l', phi'', l''``."""
    return W[at + LEN2 * B], W[at + W1 * B], W[at + L1_2 * B], W[at + W2 * B], W[at + L2_2 * B]
