"""``error_vs_runtime.md`` and ``.png``: seconds per sample against error, per method and n."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from exo_bench.bench.output.provenance import provenance
from exo_bench.bench.perf.reports.loading import _inverse, _kernel, _skips_md
from exo_bench.bench.perf.reports.loading import _log_log_by_dim, _style


# ----------------------------------------------------------------------------- error vs runtime
def error_vs_runtime(df: pd.DataFrame, skips: list[dict], command: str, png: Path) -> str:
    inv = _inverse(df)
    lines = ["# Error against run time", "", provenance(command), ""]
    if inv.empty:
        return "\n".join(lines + ["No numeric inverse-dynamics rows in this run."]) + "\n"
    bat = inv[inv["batched"]].sort_values(["dim", "method", "n"])
    lines += [
        "Batched inverse dynamics along a smooth random motion (chains, and the paper's five-link model "
        "`exo5`): median seconds per sample against the largest error over a subsample, relative to the "
        "largest |tau| of the 50-digit reference (the reference used is named in each row). An error of "
        "0 means the float64 result equals the correctly rounded 50-digit one.",
        "",
        "| dim | method | model | samples | us/sample | max abs error | max rel error | NaN/Inf | reference |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for _, r in bat.iterrows():
        lines.append(
            f"| {r['dim']}D | {r['method']} | {r['mechanism']} | {r['samples']} | {r['us_per_sample']:.3g} | "
            f"{r['max_abs_err']:.1e} | {r['max_rel_err']:.1e} | {r['nonfinite']} | {r['reference']} |"
        )
    per = inv[~inv["batched"]].sort_values(["dim", "method", "n"])
    if not per.empty:
        lines += [
            "",
            "Per call (one sample per call, `check=False`, preallocated `out`): the same error measure.",
            "",
            "| dim | method | model | us/call | max abs error | max rel error | NaN/Inf | reference |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for _, r in per.iterrows():
            lines.append(
                f"| {r['dim']}D | {r['method']} | {r['mechanism']} | {r['median'] * 1e6:.3g} | "
                f"{r['max_abs_err']:.1e} | {r['max_rel_err']:.1e} | {r['nonfinite']} | {r['reference']} |"
            )
    from exo_bench.bench.perf.peers import engine_section  # the engines' rows and their ratios

    lines += [""] + engine_section(inv)
    lines += _skips_md(skips, "test_inverse_batched")
    _plot_error_vs_runtime(bat, png)
    lines += ["", f"![error against run time]({png.name})"]
    return "\n".join(lines) + "\n"


def _plot_error_vs_runtime(bat: pd.DataFrame, png: Path) -> None:
    floor = 1e-17
    methods = sorted(bat["method"].unique())
    markers = {"numba": "o", "numpy": "s"}

    def draw(ax, dim):
        for method, g in bat[bat["dim"] == dim].groupby("method"):
            ax.scatter(
                g["us_per_sample"] * 1e-6,
                np.maximum(g["max_rel_err"], floor),
                label=method,
                marker=markers.get(_kernel(method), "D"),
                color=_style(method, methods)["color"],
                s=12 + 14 * np.log2(g["n"].to_numpy(float) + 1),
                alpha=0.85,
                edgecolors="black",
                linewidths=0.4,
            )

    _log_log_by_dim(
        png,
        draw,
        "seconds per sample (batched, median)",
        f"max relative error vs 50-digit reference (floored at {floor:g})",
        "Inverse dynamics: error against run time",
        note=(
            f"One point per (method, n): the marker's area grows with the number of links n "
            f"(n = {int(bat['n'].min())} … {int(bat['n'].max())}); circles: numba kernels, squares: "
            "numpy kernels, diamonds: the others. Errors below the floor are drawn at the floor."
        ),
    )
