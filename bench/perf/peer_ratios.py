"""The rigid-body engines as peers in the benchmark reports: what their rows time, and their time as
a multiple of ``matrix-factored`` and of ``newton-euler`` (where a run has that method's rows).

Used by :func:`exo_bench.bench.perf.reports.benchmark_reports.scaling` and :func:`exo_bench.bench.perf.reports.benchmark_reports.error_vs_runtime`: one
section each, from the rows of the same run (ratios of timings from one run on one host only).
A ratio's denominator is the fastest row of the base method on the same mechanism, batched or per
call alike (``matrix-factored (numba)`` or ``(numpy)``, any ``newton-euler`` kernel), and the row
that won is named.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from exo_bench.api import METHODS

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
