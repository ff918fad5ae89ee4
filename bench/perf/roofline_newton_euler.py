"""Where the limit is for ``newton-euler``'s kernel that vectorises across samples (models/newton_euler/simd.py).

Counted like :func:`exo_bench.bench.perf.roofline_simd.count_simd`: the kernel's own steps (their
``py_func``: the forward pass with its start points, the backward pass) run one sample on arrays of
:class:`exo_bench.bench.perf.roofline.Counted` numbers, with the element functions of
models/mechanism/rod_elements.py and the branch-free ``sin``/``cos``
(:func:`exo_bench.models.machine.fast_trig.sincos_reduced`, whose ``floor`` counts as one flop) as they are:
every ``+``, ``-``, ``*`` and ``floor`` of the code that runs is counted, the arithmetic sine and
cosine included, and the per-mechanism numbers are counted numbers too (so a root's ``eta * 0``
counts, as the compiled loop does it). Not counted: the comparisons and selects of the range check
and of the quadrant, the loads and stores of the two transposes.

The limit of one sample is its flops at the SIMD rate (:func:`exo_bench.bench.perf.roofline_simd.estimate_simd`).
"""

from __future__ import annotations

import types

import numpy as np

from exo_bench.bench.perf.roofline import Counted, rebind
from exo_bench.bench.perf.roofline_simd import _floor, _fma, estimate_simd
from exo_bench.models.mechanism.mechanism import Mechanism

__all__ = ["count_newton_euler_simd", "estimate_simd"]


def _no_prefetch(*args) -> None:
    """The prefetches of the next block (no arithmetic, and no memory in this counting run)."""


def count_newton_euler_simd(mech: Mechanism, q, qd, qdd) -> tuple[dict[str, int], np.ndarray]:
    """Flops of one sample ``(dof,)`` of the newton-euler SIMD kernel on ``mech`` (module docstring),
    and the forces that run computed (the compiled SIMD kernel's, to the bit: the same operations)."""
    from exo_bench.models.machine import fast_trig, simd_angles
    from exo_bench.models.newton_euler import simd
    from exo_bench.models.newton_euler.tree import prepare_tree
    from exo_bench.models.machine.simd_blocks import FROWS, LANES, ROWS, _rows_in_by_link, _rows_out_by_link

    trig = rebind(fast_trig.sincos_reduced, math=types.SimpleNamespace(floor=_floor), fma=_fma)
    start = rebind(simd._start_points.py_func)
    forward = rebind(
        (simd._forward_2d if mech.dim == 2 else simd._forward_3d).py_func,
        link_pass=rebind(simd_angles.link_pass, sincos_reduced=trig),
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
