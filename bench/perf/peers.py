"""Peers of the benchmark outside this package: PyDy's Cython code generator.

What a sympy user would reach for to make equations of motion fast: PyDy's
``CythonMatrixGenerator`` turns sympy expressions into C (with common subexpressions eliminated),
wraps it with Cython and compiles it. Here it gets the same composed equations as our methods,
:func:`exo_bench.matrix_method.symbolic.compose.compose_equations` (eq. (5)/(17), the mechanism's
parameters as exact rationals), as one column of ``dof`` expressions in the inputs ``q, qd, qdd``.

Optional: ``pip install exo-bench[peers]`` (pydy, cython) and a C compiler.
:func:`missing` says in words what is absent, so that the benchmark can skip with that reason.
"""

from __future__ import annotations

import importlib.util
import shutil
import time
from dataclasses import dataclass
from collections.abc import Callable

import numpy as np

from exo_bench.models.machine.bounded_cache import BoundedCache
from exo_bench.models.mechanism.mechanism import Mechanism


def missing() -> str | None:
    """Why the PyDy row cannot run here, or None when it can."""
    absent = [m for m in ("pydy", "Cython", "setuptools") if importlib.util.find_spec(m) is None]
    if absent:
        return (
            f"PyDy Cython peer not installed ({', '.join(absent)} missing): "
            "pip install 'exo-bench[peers]' to run this row"
        )
    if not (shutil.which("cc") or shutil.which("gcc")):
        return "PyDy Cython peer: no C compiler (cc/gcc) on PATH"
    return None


@dataclass(frozen=True)
class PydyFunction:
    """The compiled PyDy function of one mechanism: ``call(q, qd, qdd, out)`` writes the forces
    (block order) into ``out`` and returns it; ``seconds`` is the time to compose, generate and compile."""

    call: Callable
    seconds: float
    compose_seconds: float


#: PyDy's compiled functions of the latest mechanisms (bounded: models/machine/bounded_cache.py; a dropped one's
#: extension module stays imported, as Python cannot unload it, but its generated sources are freed).
_CACHE: BoundedCache[Mechanism, PydyFunction] = BoundedCache(16)


def pydy_cython(mech: Mechanism) -> PydyFunction:
    """Compose the mechanism's equations with the matrix method and compile them with PyDy's
    ``CythonMatrixGenerator`` (cse on); cached per mechanism for the process."""
    if mech in _CACHE:
        return _CACHE[mech]
    import sympy as sp
    from pydy.codegen.cython_code import CythonMatrixGenerator

    from exo_bench.matrix_method.symbolic.compose import compose_equations
    from exo_bench.models.mechanism.symbols import symbols_for

    t0 = time.perf_counter()
    eqs = compose_equations(mech)
    t1 = time.perf_counter()
    S = symbols_for(mech.nlinks, mech.dim)
    gen = CythonMatrixGenerator(
        [list(S.q), list(S.qd), list(S.qdd)], [sp.Matrix(eqs)], prefix=f"exo_bench_pydy_{mech.dim}d{mech.nlinks}"
    )
    fn = gen.compile()
    f = PydyFunction(call=fn, seconds=time.perf_counter() - t0, compose_seconds=t1 - t0)
    _CACHE[mech] = f
    return f


def evaluate(f: PydyFunction, q, qd, qdd) -> np.ndarray:
    """The PyDy function on ``(samples, dof)`` states, one call per sample: ``(samples, dof)``."""
    q, qd, qdd = (np.ascontiguousarray(x, dtype=float) for x in (q, qd, qdd))
    out = np.empty_like(q)
    for s in range(q.shape[0]):
        f.call(q[s], qd[s], qdd[s], out[s])
    return out
