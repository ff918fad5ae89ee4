"""Forward dynamics of one sample checked in one compiled call: the ``tree-forward`` kernel's
(:mod:`exo_bench.models.newton_euler.kernels`). :func:`checked_forward` runs the common-case check of
:mod:`exo_bench.models.runtime.forward_check` (``clear``), newton-euler's forward passes
(:mod:`exo_bench.models.newton_euler.compiled`) and ``finite``, answering :data:`DONE`, :data:`EXACT`
(nothing computed: the exact checks decide) or :data:`NOT_FINITE`."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from exo_bench.models.machine.numba_runtime import JIT, ensure, jit_disabled

ensure()  # numba's runtime set-up (models/machine/numba_runtime.py), before the first kernel is defined

from numba import njit, types  # noqa: E402

from exo_bench.models.runtime.forward_check import _DIM, _G, DONE, EXACT, NOT_FINITE, _finite, _row_clear  # noqa: E402
from exo_bench.models.newton_euler.compiled import WIDTH, _forward_sample  # noqa: E402

__all__ = ["DONE", "EXACT", "NOT_FINITE", "checked_forward", "entry"]


@njit(**JIT)
def checked_forward(t, p, x, xd, tau, o):
    """One validated sample: :data:`EXACT` unless ``x`` clears the bounds, else forward dynamics into
    ``o`` and :data:`DONE`, or :data:`NOT_FINITE` where an entry of ``o`` is not finite."""
    n = t.shape[1]
    if not _row_clear(x, 0, x.shape[0], n, p):
        return EXACT
    _forward_sample(t, p[_G], int(p[_DIM]), x, xd, tau, o, 0, np.zeros((n, WIDTH)))
    return DONE if _finite(o) else NOT_FINITE


@functools.cache
def entry() -> Any:
    """The compiled entry point of :func:`checked_forward` (or the function itself under
    ``NUMBA_DISABLE_JIT``), resolved on the first call in a process."""
    if jit_disabled():
        return checked_forward
    one, two = types.Array(types.float64, 1, "C"), types.Array(types.float64, 2, "C")
    return checked_forward.compile((two, one, one, one, one, one))
