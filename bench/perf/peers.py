"""Peers of the benchmark outside this package: PyDy's Cython code generator, and the rigid-body engines
(what their rows time, and their time as a multiple of ours in the reports).

What a sympy user would reach for to make equations of motion fast: PyDy's
``CythonMatrixGenerator`` turns sympy expressions into C (with common subexpressions eliminated),
wraps it with Cython and compiles it. Here it gets the same composed equations as our methods,
:func:`exo_bench.matrix_method.symbolic.compose_equations` (eq. (5)/(17), the mechanism's
parameters as exact rationals), as one column of ``dof`` expressions in the inputs ``q, qd, qdd``.

Optional: ``pip install exo-bench[peers]`` (pydy, cython) and a C compiler.
:func:`missing` says in words what is absent, so that the benchmark can skip with that reason.
"""

from __future__ import annotations

import importlib.util
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pandas as pd

from exo_bench.models.machine.memory import BoundedCache
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.api import METHODS


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


#: PyDy's compiled functions of the latest mechanisms (bounded: models/machine/memory.py; a dropped one's
#: extension module stays imported, as Python cannot unload it, but its generated sources are freed).
_CACHE: BoundedCache[Mechanism, PydyFunction] = BoundedCache(16)


def pydy_cython(mech: Mechanism) -> PydyFunction:
    """Compose the mechanism's equations with the matrix method and compile them with PyDy's
    ``CythonMatrixGenerator`` (cse on); cached per mechanism for the process."""
    if mech in _CACHE:
        return _CACHE[mech]
    import sympy as sp
    from pydy.codegen.cython_code import CythonMatrixGenerator

    from exo_bench.matrix_method.symbolic import compose_equations
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


# The rigid-body engines as peers in the benchmark reports: what their rows time, and their time as a multiple
# of ``matrix-factored`` and of ``newton-euler`` (where a run has that method's rows).

#: The engines, and what one of their rows times (their MethodSpecs).
ENGINES = {name: s.engine_row for name, s in METHODS.items() if s.engine_row}
#: Per call, each engine's own calls without the G maps and the wrapper (bench/test_inverse_dynamics.py).
BARE = {name: s.bare_row for name, s in METHODS.items() if s.bare_row}
#: The denominators of the ratios: the suite's fastest method, and (from another branch) O(n) Newton-Euler.
REFERENCES = ("matrix-factored", "newton-euler")


def _base(row: str) -> str:
    return str(row).split(" (")[0]


def _fastest(sub: pd.DataFrame, base: str, value: str) -> tuple[float, str] | None:
    rows = sub[sub["method"].map(_base) == base]
    if rows.empty:
        return None
    r = rows.loc[rows[value].idxmin()]
    return float(r[value]), str(r["method"])


def engine_section(inv: pd.DataFrame, batched: bool | None = None) -> list[str]:
    """Markdown lines: the engines' rows of this run (per call and batched, or one of them), in us,
    with their ratio to each reference present in the run."""
    if inv.empty:
        return []
    inv = inv.copy()
    inv["us_per_call"] = inv["median"] * 1e6
    present = [e for e in ENGINES if e in set(inv["method"].map(_base))]
    if not present:
        return []
    refs = [r for r in REFERENCES if r in set(inv["method"].map(_base))]
    out = ["## The rigid-body engines as peers", "", "What each engine's row times:", ""] + [
        f"- `{e}`: {ENGINES[e]}." for e in present
    ]
    out += [
        "",
        "Per call, `bare engine` is the engine's own calls on preallocated joint coordinates (`pin.rnea "
        "(bare)`, `mj_rne (bare)`, `CalcInverseDynamics (bare)`: no G maps, no wrapper) and `overhead` the "
        "method's time beyond them (the G maps, the prepared model's call, the per-sample loop).",
    ]
    out += [
        "",
        "Each row's time as a multiple of the fastest row of "
        + " and of ".join(f"`{r}`" for r in refs)
        + " on the same model in this run (that row named); above 1: the engine is slower."
        + "".join(f" (No `{r}` rows in this run.)" for r in REFERENCES if r not in refs),
        "",
    ]
    modes = [(False, "per call", "us_per_call"), (True, "batched", "us_per_sample")]
    for is_batched, label, value in modes:
        if batched is not None and is_batched != batched:
            continue
        sub = inv[inv["batched"] == is_batched]
        if sub.empty:
            continue
        bare = not is_batched and bool(set(BARE.values()) & set(sub["method"]))
        head = (
            f"| {label} | model | us | "
            + ("bare engine us | overhead us | " if bare else "")
            + " | ".join(f"x {r}" for r in refs)
            + " |"
        )
        lines = [head, "|---|---|---|" + ("---|---|" if bare else "") + "---|" * len(refs)]
        for mech in sorted(sub["mechanism"].unique(), key=lambda m: (m != "exo5-3d", m)):
            at = sub[sub["mechanism"] == mech]
            for e in present:
                row = at[at["method"].map(_base) == e]
                if row.empty:
                    continue
                for _, r in row.iterrows():
                    cells = []
                    for ref in refs:
                        f = _fastest(at, ref, value)
                        cells.append("-" if f is None else f"{r[value] / f[0]:.3g} (`{f[1]}`)")
                    extra = ""
                    if bare:
                        b_row = at[at["method"] == BARE[e]]
                        b_us = float(b_row[value].iloc[0]) if not b_row.empty else np.nan
                        extra = "- | - | " if np.isnan(b_us) else f"{b_us:.3g} | {r[value] - b_us:.3g} | "
                    lines.append(f"| `{r['method']}` | {mech} | {r[value]:.3g} | " + extra + " | ".join(cells) + " |")
        if len(lines) > 2:
            out += [f"### {label.capitalize()}", ""] + lines + [""]
    return out


def ratios(inv: pd.DataFrame, engine: str, reference: str, batched: bool) -> dict[str, float]:
    """``mechanism -> engine time / fastest reference time`` (NaN where either is missing): the
    numbers of :func:`engine_section`, for tests and callers."""
    value = "us_per_sample" if batched else "median"
    sub = inv[inv["batched"] == batched]
    out = {}
    for mech, at in sub.groupby("mechanism"):
        e = _fastest(at, engine, value)
        f = _fastest(at, reference, value)
        out[mech] = np.nan if e is None or f is None else e[0] / f[0]
    return out
