"""``exo-bench bench``: run the benchmark suite and generate its reports with pandas.

Reports (each says what produced it, on what machine and when):

* ``reports/paper_table.md``: the paper's Mathematica timings beside ours, our extra rows, ratios,
  and a verdict on the claim that the gap grows with n and with 3D;
* ``reports/error_vs_runtime.md`` and ``.png``: seconds per sample against error, per method and n;
* ``reports/scaling.md`` and ``.png``: issue 12's goals met or not, the per-call and batched tables
  (compiled and numpy kernels, Pinocchio bare and parallel, PyDy's Cython code), fitted growth
  exponents, the crossover n against Pinocchio, the kernels' compile time, and where the limit is
  (the factored kernel's counted arithmetic at this CPU's measured rates).

The raw pytest-benchmark JSON is kept beside them (``reports/benchmarks-<sweep>.json``).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from exo_bench.bench import simd_goals
from exo_bench.bench.reporting import REPO, REPORTS, atomic_write, provenance
from exo_bench.bench.rows import check_ratio_groups
from exo_bench.bench.runner import publish, staging_dir

# The paper's table (section 7), seconds in Mathematica to compose the equations.
PAPER_TABLE = [
    # dim, n, topology, Lagrange II, matrix method, recurrence
    (2, 1, "chain", 0.59, 0.46, None),
    (2, 2, "chain", 5.3, 0.55, 0.59),
    (2, 3, "chain", 37.0, 0.79, 0.86),
    (3, 2, "chain", 113.69, 1.30, None),
]

GOAL_US_PER_SAMPLE = 0.5
GOAL_ERR = 1e-12
GOAL_COMPOSE_3D5_S = 0.050
GOAL_RATIO_3D2 = 100.0


def load(json_path: Path, skips_path: Path | None = None) -> tuple[pd.DataFrame, list[dict], dict]:
    data = json.loads(Path(json_path).read_text())
    rows = []
    for b in data.get("benchmarks", []):
        info = dict(b.get("extra_info", {}))
        st = b["stats"]
        info.update(group=b["group"], name=b["name"], median=st["median"], min=st["min"], mean=st["mean"],
                    rounds=st["rounds"], iqr=st.get("iqr", float("nan")))
        rows.append(info)
    skips = json.loads(Path(skips_path).read_text()) if skips_path and Path(skips_path).exists() else []
    check_ratio_groups(pd.DataFrame(rows))   # never a ratio of timings from two hosts (bench/rows.py)
    return pd.DataFrame(rows), skips, data.get("machine_info", {})


def _base(row_name: str) -> str:
    """The method of a row name (``"matrix-factored (numba)"`` -> ``"matrix-factored"``)."""
    return str(row_name).split(" (")[0]


def _kernel(row_name: str) -> str:
    """What the row name says in brackets after the method (``"matrix (numba)"`` -> ``"numba"``,
    ``"pin.rnea (bare)"`` -> ``"bare"``, ``"pinocchio"`` -> ``""``)."""
    return str(row_name)[len(_base(row_name)):].strip(" ()")


def _inverse(df: pd.DataFrame) -> pd.DataFrame:
    if df.empty or "batched" not in df:
        return pd.DataFrame()
    inv = df[df["group"].str.startswith("inverse")].copy()
    inv["batched"] = inv["batched"].astype(bool)   # object dtype beside the compose rows; ~ needs bools
    inv["us_per_sample"] = inv["median"] / inv["samples"] * 1e6
    return inv


def _skips_md(skips: list[dict], prefix: str) -> list[str]:
    rel = [s for s in skips if prefix in s["nodeid"]]
    if not rel:
        return []
    out = ["", "Skipped rows (with the reason recorded by the benchmark):", ""]
    out += [f"- `{s['nodeid'].split('::')[-1]}`: {s['reason']}" for s in rel]
    return out


# ----------------------------------------------------------------------------- error vs runtime
def error_vs_runtime(df: pd.DataFrame, skips: list[dict], command: str, png: Path) -> str:
    inv = _inverse(df)
    lines = ["# Error against run time", "", provenance(command), ""]
    if inv.empty:
        return "\n".join(lines + ["No numeric inverse-dynamics rows in this run."]) + "\n"
    bat = inv[inv["batched"]].sort_values(["dim", "method", "n"])
    lines += ["Batched inverse dynamics along a smooth random motion (chains, and the paper's five-link model "
              "`exo5`): median seconds per sample against the largest error over a subsample, relative to the "
              "largest |tau| of the 50-digit reference (the reference used is named in each row). An error of "
              "0 means the float64 result equals the correctly rounded 50-digit one.", "",
              "| dim | method | model | samples | us/sample | max abs error | max rel error | NaN/Inf | reference |",
              "|---|---|---|---|---|---|---|---|---|"]
    for _, r in bat.iterrows():
        lines.append(f"| {r['dim']}D | {r['method']} | {r['mechanism']} | {r['samples']} | {r['us_per_sample']:.3g} | "
                     f"{r['max_abs_err']:.1e} | {r['max_rel_err']:.1e} | {r['nonfinite']} | {r['reference']} |")
    per = inv[~inv["batched"]].sort_values(["dim", "method", "n"])
    if not per.empty:
        lines += ["", "Per call (one sample per call, `check=False`, preallocated `out`): the same error measure.", "",
                  "| dim | method | model | us/call | max abs error | max rel error | NaN/Inf | reference |",
                  "|---|---|---|---|---|---|---|---|"]
        for _, r in per.iterrows():
            lines.append(f"| {r['dim']}D | {r['method']} | {r['mechanism']} | {r['median'] * 1e6:.3g} | "
                         f"{r['max_abs_err']:.1e} | {r['max_rel_err']:.1e} | {r['nonfinite']} | {r['reference']} |")
    from exo_bench.bench.peer_ratios import engine_section  # the engines' rows and their ratios

    lines += [""] + engine_section(inv)
    lines += _skips_md(skips, "test_inverse_batched")
    _plot_error_vs_runtime(bat, png)
    lines += ["", f"![error against run time]({png.name})"]
    return "\n".join(lines) + "\n"


def _log_log_by_dim(png: Path, draw, xlabel: str, ylabel: str, title: str, panel_title: str = "{dim}D",
                    note: str = "") -> None:
    """One log-log panel per dimension (2D, 3D) sharing the y axis; ``draw(ax, dim)`` plots a panel.
    One legend for both panels, outside the data (right of them), and ``note`` under the panels."""
    from matplotlib.figure import Figure

    from exo_bench.bench.plots import TEXT_PT, TITLE_PT, save_figure

    fig = Figure(figsize=(15, 6.5), layout="constrained")
    axes = fig.subplots(1, 2, sharey=True)
    for ax, dim in zip(axes, (2, 3)):
        draw(ax, dim)
        ax.set_xscale("log"); ax.set_yscale("log")
        ax.set_xlabel(xlabel, fontsize=TEXT_PT)
        ax.set_title(panel_title.format(dim=dim), fontsize=TITLE_PT)
        ax.tick_params(labelsize=TEXT_PT)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(ylabel, fontsize=TEXT_PT)
    handles: dict = {}
    for ax in axes:
        for h, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, h)
    fig.legend(list(handles.values()), list(handles), loc="outside right upper", fontsize=TEXT_PT)
    if note:
        fig.text(0.01, 0.0, note, fontsize=TEXT_PT, ha="left", va="bottom", wrap=True)
        fig.get_layout_engine().set(rect=(0, 0.06, 1, 0.94))
    fig.suptitle(title, fontsize=TITLE_PT + 1)
    save_figure(fig, png)


def _style(method: str, methods) -> dict:
    """Colour from the base method (the same as in every scene figure), line style from the kernel:
    ``matrix (numba)`` solid, ``matrix (numpy)`` dashed; other rows (pin.rnea, PyDy) dash-dot."""
    from exo_bench.bench.plots import method_color

    bases = sorted({_base(m) for m in methods})
    return {"color": method_color(_base(method), bases),
            "ls": {"numba": "-", "numpy": "--", "": "-"}.get(_kernel(method), "-.")}


def _plot_error_vs_runtime(bat: pd.DataFrame, png: Path) -> None:
    floor = 1e-17
    methods = sorted(bat["method"].unique())
    markers = {"numba": "o", "numpy": "s"}

    def draw(ax, dim):
        for method, g in bat[bat["dim"] == dim].groupby("method"):
            ax.scatter(g["us_per_sample"] * 1e-6, np.maximum(g["max_rel_err"], floor), label=method,
                       marker=markers.get(_kernel(method), "D"), color=_style(method, methods)["color"],
                       s=12 + 14 * np.log2(g["n"].to_numpy(float) + 1), alpha=0.85, edgecolors="black", linewidths=0.4)

    _log_log_by_dim(png, draw, "seconds per sample (batched, median)",
                    f"max relative error vs 50-digit reference (floored at {floor:g})",
                    "Inverse dynamics: error against run time",
                    note=(f"One point per (method, n): the marker's area grows with the number of links n "
                          f"(n = {int(bat['n'].min())} … {int(bat['n'].max())}); circles: numba kernels, squares: "
                          "numpy kernels, diamonds: the others. Errors below the floor are drawn at the floor."))


# ----------------------------------------------------------------------------- scaling
def fit_exponent(n: np.ndarray, t: np.ndarray) -> float:
    """Least-squares slope of log t against log n (the growth exponent p in t ~ n^p)."""
    mask = n >= 2
    if mask.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(n[mask]), np.log(t[mask]), 1)[0])


def crossover(a: pd.Series, b: pd.Series) -> str:
    """The smallest n from which ``b`` (indexed by n) is faster than ``a`` and stays faster."""
    common = sorted(set(a.index) & set(b.index))
    if not common:
        return "no common n"
    faster = [b[n] < a[n] for n in common]
    for k, n in enumerate(common):
        if all(faster[k:]):
            return f"n = {n}" if k > 0 else f"already at n = {n} (smallest measured)"
    return f"none up to n = {common[-1]}"


MATRIX_FAMILY = ("matrix-factored", "matrix", "recurrence")
FAST = "matrix-factored (numba)"
PIN_BARE = "pin.rnea (bare)"
PYDY = "pydy-cython"
#: Issue 12's goals (ratios from one run on one machine).
GOAL12_PER_CALL_VS_RNEA = 0.5      # matrix-factored per call, exo5-3d, at most this x bare pin.rnea
GOAL12_US_PER_SAMPLE = 0.15        # matrix-factored batched, exo5-3d, 10,000 samples
GOAL12_VS_PIN_BATCHED = 30.0       # ... at least this much faster than Pinocchio's best batched path
GOAL12_REL_ERR = 1e-14             # every row, against the 50-digit reference


def _met(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


def _pin_best_batched(d: pd.DataFrame) -> pd.Series:
    """Pinocchio's fastest batched path per n (``pinocchio`` loop or ``pinocchio-parallel``), us/sample."""
    pin = d[d["method"].isin(["pinocchio", "pinocchio-parallel"])]
    return pin.groupby("n")["us_per_sample"].min()


def goals_issue12(inv: pd.DataFrame, skips: list[dict]) -> list[str]:
    """Issue 12's goals, each met or not met with the measured ratio (rows of this run only)."""
    out = ["## Goals (issue 12)", "", "Ratios compare rows of this one run on this one machine "
           "(indicative where the machine was shared).", ""]
    exo = inv[inv["mechanism"] == "exo5-3d"]
    per = exo[~exo["batched"]].set_index("method")["median"] * 1e6
    bat = exo[exo["batched"]].set_index("method")["us_per_sample"]
    if FAST in per.index and PIN_BARE in per.index:
        r = per[FAST] / per[PIN_BARE]
        out.append(f"- Per call, exo5-3d, `check=False`: `{FAST}` {per[FAST]:.3g} us, bare `pin.rnea` "
                   f"{per[PIN_BARE]:.3g} us: {r:.2f}x, goal at most {GOAL12_PER_CALL_VS_RNEA}x: "
                   f"{_met(r <= GOAL12_PER_CALL_VS_RNEA)}.")
    else:
        out.append(f"- Per call against bare `pin.rnea`: not measured in this run (`{FAST}` or `{PIN_BARE}` missing).")
    if FAST in per.index and PYDY in per.index:
        r = per[FAST] / per[PYDY]
        out.append(f"- Per call, exo5-3d: `{FAST}` {per[FAST]:.3g} us, PyDy's Cython code {per[PYDY]:.3g} us: "
                   f"{r:.2f}x, goal at most 1x: {_met(r <= 1.0)}.")
    else:
        out.append(f"- Per call against PyDy's Cython code: not measured in this run (PyDy row skipped: "
                   "`pip install 'exo-bench[peers]'`).")
    if FAST in bat.index:
        us = bat[FAST]
        samples = int(exo[exo["batched"] & (exo["method"] == FAST)]["samples"].iloc[0])
        out.append(f"- Batched, exo5-3d, {samples:,} samples: `{FAST}` {us:.3g} us/sample, goal at most "
                   f"{GOAL12_US_PER_SAMPLE} us: {_met(us <= GOAL12_US_PER_SAMPLE)}"
                   + ("" if samples >= 10_000 else " (quick profile: fewer samples than the goal's 10,000)") + ".")
        pin = {m: bat[m] for m in ("pinocchio", "pinocchio-parallel") if m in bat.index}
        if pin:
            best = min(pin, key=pin.get)
            threads = exo[exo["batched"] & (exo["method"] == best)]["threads"].iloc[0] if "threads" in exo else ""
            r = pin[best] / us
            out.append(f"- Batched, exo5-3d: Pinocchio's best batched path `{best}`"
                       + (f" ({threads} threads)" if best == "pinocchio-parallel" and threads != "" else "")
                       + f" {pin[best]:.3g} us/sample, {r:.3g}x slower than `{FAST}`; goal at least "
                       f"{GOAL12_VS_PIN_BATCHED:g}x: {_met(r >= GOAL12_VS_PIN_BATCHED)}.")
    else:
        out.append(f"- Batched, exo5-3d: no `{FAST}` row in this run.")
    big = inv[inv["batched"] & (inv["dim"] == 3) & (inv["n"] == 100) & (inv["topology"] == "chain")] \
        if "topology" in inv else inv.iloc[:0]
    fam = [f"{m} (numba)" for m in MATRIX_FAMILY]
    if big.empty:
        out.append("- n = 100 in 3D, batched: not in this profile (`exo-bench bench --full`).")
    else:
        done = set(big["method"])
        missing = [m for m in fam if m not in done]
        slow = sorted(m for m in set(inv["method"]) if _base(m) in MATRIX_FAMILY and m not in fam and m not in done)
        out.append(f"- n = 100 in 3D, batched: every matrix-family method (compiled, the default kernel) finishes: "
                   f"{_met(not missing)}" + (f" (skipped: {', '.join(missing)})" if missing else f" ({', '.join(fam)})")
                   + (f"; over the time budget: {', '.join(slow)}" if slow else "") + ".")
    ok = inv[~((inv["method"] == "matrix-paper") & (inv["dim"] == 3) & (inv["n"] > 1))]
    worst = ok.loc[ok["max_rel_err"].idxmax()] if not ok.empty else None
    if worst is not None:
        over = ok[ok["max_rel_err"] > GOAL12_REL_ERR]
        out.append(f"- Error at most {GOAL12_REL_ERR:g} relative against the 50-digit reference on every row "
                   f"(matrix-paper in 3D excepted: wrong by design): largest {worst['max_rel_err']:.1e} "
                   f"(`{worst['method']}`, {worst['mechanism']}, {'batched' if worst['batched'] else 'per call'}): "
                   f"{_met(over.empty)}" + ("" if over.empty else f" ({len(over)} rows above)") + ".")
    return out + [""]


def _table(sub: pd.DataFrame, value: str, cols: list, fmt=lambda v: f"{v:.3g}", exponent: bool = False) -> list[str]:
    """Rows: methods; columns ``(mechanism label, n)`` pairs in ``cols``."""
    head = "| method | " + " | ".join(c[0] for c in cols) + (" | exponent p |" if exponent else " |")
    lines = [head, "|---|" + "---|" * (len(cols) + (1 if exponent else 0))]
    for method, g in sub.groupby("method"):
        cells, ns, ts = [], [], []
        for label, mech in cols:
            r = g[g["mechanism"] == mech]
            if r.empty:
                cells.append("skipped")
            else:
                v = float(r[value].iloc[0])
                cells.append(fmt(v))
                if mech.startswith("chain"):
                    ns.append(int(r["n"].iloc[0])); ts.append(v)
        p = f" | {fit_exponent(np.array(ns, float), np.array(ts, float)):.2f}" if exponent else ""
        lines.append(f"| {method} | " + " | ".join(cells) + p + " |")
    return lines


def compile_section(df: pd.DataFrame) -> list[str]:
    c = df[df["group"] == "compile"] if not df.empty else df
    if c.empty or "compile" not in c:
        return []
    info = c.iloc[0]["compile"]
    out = ["## Compile time of the compiled kernels", "",
           "First call of each numba kernel on exo5-3d in a fresh process with an empty numba cache (compiling), "
           "and in a second process with that cache (loading the machine code): numba's on-disk cache means "
           "a user pays the compile once per machine (and after an edit of the kernel's file). The first kernel "
           "loaded in a process also pays numba's own start-up.", "",
           "| method | driver | first call, empty cache (s) | first call, from the cache (ms) |", "|---|---|---|---|"]
    for m, drivers in info.items():
        for d, v in drivers.items():
            out.append(f"| {m} | {d} | {v['first_call_s']:.2f} | {v['from_cache_s'] * 1e3:.1f} |")
    return out + [""]


def limit_section(df: pd.DataFrame, inv: pd.DataFrame) -> list[str]:
    lim = df[df["group"] == "limit"] if not df.empty else df
    if lim.empty or "count" not in lim:
        return []
    r = lim.iloc[0]
    count, rates, est, threads = r["count"], r["rates"], r["estimate"], int(r["numba_threads"])
    out = ["## Where the limit is", "",
           "One exo5-3d sample of the factored kernel (`matrix_method/compiled_factored.py`), counted by running the "
           "kernel's own per-sample function on counting floats (`bench/limit.py`; the counting run gives the "
           "compiled kernel's forces bit for bit):", "",
           f"- {count['add']} additions/subtractions and {count['mul']} multiplications ({count['flops']} flops), "
           f"{count['trig']} transcendental calls (cos, sin).",
           f"- This CPU, one core, measured with numba loops compiled like the kernels (`bench/limit.py`): "
           f"{rates['scalar_flops_per_s'] / 1e9:.3g} Gflop/s scalar, {rates['simd_flops_per_s'] / 1e9:.3g} Gflop/s "
           f"SIMD (multiply-adds), {rates['sincos_per_s'] / 1e6:.3g} M angles/s for `cos` and `sin` of one angle "
           f"({1e9 / rates['sincos_per_s']:.3g} ns each pair).",
           f"- Estimate for one sample on one core: {est['scalar_s'] * 1e9:.3g} ns with the flops scalar, "
           f"{est['simd_s'] * 1e9:.3g} ns with the flops at the SIMD rate (of which {est['trig_s'] * 1e9:.3g} ns are "
           f"the {count['trig'] // 2} angles); on the {threads} threads numba uses, "
           f"{est['scalar_s'] / threads * 1e9:.3g} and {est['simd_s'] / threads * 1e9:.3g} ns per sample."]
    exo = inv[(inv["mechanism"] == "exo5-3d") & (inv["method"] == FAST)] if not inv.empty else inv
    bat, per = exo[exo["batched"]], exo[~exo["batched"]]
    if not bat.empty:
        us = float(bat["us_per_sample"].iloc[0])
        out.append(f"- Measured, batched on {threads} threads: {us * 1e3:.3g} ns per sample: "
                   f"{us * 1e-6 / (est['scalar_s'] / threads):.2g}x the scalar estimate, "
                   f"{us * 1e-6 / (est['simd_s'] / threads):.2g}x the SIMD estimate (on a machine shared with "
                   "other jobs the threads do not get whole cores: compare with one core's estimate, "
                   f"{us * 1e-6 / est['scalar_s']:.2g}x and {us * 1e-6 / est['simd_s']:.2g}x).")
    if not per.empty:
        t = float(per["median"].iloc[0])
        out.append(f"- Measured per call (one sample, from Python): {t * 1e9:.3g} ns, {t / est['scalar_s']:.2g}x the "
                   "scalar estimate: the rest is the call (numba's dispatch of the arrays, the model's method).")
    return out + [""]


def scaling(df: pd.DataFrame, skips: list[dict], command: str, png: Path) -> str:
    inv = _inverse(df)
    lines = ["# Scaling with the number of links", "", provenance(command), ""]
    if inv.empty:
        return "\n".join(lines + ["No numeric inverse-dynamics rows in this run."]) + "\n"
    if "topology" not in inv:
        inv["topology"] = np.where(inv["mechanism"].str.startswith("chain"), "chain", "exo5")
    lines += goals_issue12(inv, skips)
    from exo_bench.bench.goals_newton_euler import goals_issue22   # newton-euler's goals and forward table
    lines += goals_issue22(df)
    per = inv[~inv["batched"]].copy()
    per["us_per_call"] = per["median"] * 1e6
    if not per.empty:
        cols = [("exo5-3d", "exo5-3d")] + [(f"{d}D n={n}", f"chain{n}-{d}d") for d in (2, 3)
                                            for n in sorted(per[per["topology"] == "chain"]["n"].unique())]
        lines += ["## Per call", "", "Microseconds per call, one sample, `check=False`, into a preallocated `out` "
                  "(`pin.rnea (bare)`: Pinocchio's own cost on preallocated joint coordinates; `pydy-cython`: PyDy's "
                  "Cython code of the same composed equations; `mujoco`, `drake`: the engines, what their rows time "
                  "below). Models: exo5-3d and serial chains of n links.", ""]
        lines += _table(per, "us_per_call", cols)
        if PIN_BARE in set(per["method"]):
            lines += ["", "The same, as a multiple of bare `pin.rnea` on the same model:", ""]
            ratio = per.copy()
            bare = per[per["method"] == PIN_BARE].set_index("mechanism")["us_per_call"]
            ratio["x_rnea"] = ratio.apply(lambda r: r["us_per_call"] / bare.get(r["mechanism"], np.nan), axis=1)
            lines += _table(ratio, "x_rnea", cols, fmt=lambda v: f"{v:.2f}x")
        lines.append("")
    bat = inv[inv["batched"]]
    if not bat.empty:
        samples = int(bat["samples"].max())
        lines += ["## Batched", "", f"Microseconds per sample, one call for {samples:,} samples along a smooth random "
                  "motion; exponent p fits cost ~ n^p over the chains with n >= 2.", ""]
        for dim in sorted(bat["dim"].unique()):
            d = bat[bat["dim"] == dim]
            cols = [(f"n={n}", f"chain{n}-{dim}d") for n in sorted(d[d["topology"] == "chain"]["n"].unique())]
            if dim == 3:
                cols = [("exo5-3d", "exo5-3d")] + cols
            lines += [f"### {dim}D", ""] + _table(d, "us_per_sample", cols, exponent=True) + [""]
    lines += ["## Crossover against Pinocchio", "",
              "The smallest n of the chains from which Pinocchio is faster than the row and stays faster "
              "(batched: Pinocchio's best batched path at each n; per call: bare `pin.rnea`).", ""]
    for label, sub, pin_of in (("batched", bat, _pin_best_batched),
                               ("per call", per, lambda d: d[d["method"] == PIN_BARE].groupby("n")["us_per_call"].min())):
        chains = sub[sub["topology"] == "chain"] if not sub.empty else sub
        value = "us_per_sample" if label == "batched" else "us_per_call"
        for dim in sorted(chains["dim"].unique()) if not chains.empty else []:
            d = chains[chains["dim"] == dim]
            pin = pin_of(d)
            for m in sorted({m for m in d["method"] if _base(m) in MATRIX_FAMILY}):
                mm = d[d["method"] == m].set_index("n")[value]
                if len(mm) and len(pin):
                    lines.append(f"- {dim}D, {label}, `{m}` against Pinocchio: crossover {crossover(mm, pin)}")
    lines.append("")
    from exo_bench.bench.peer_ratios import engine_section  # the engines' rows and their ratios

    lines += engine_section(inv)
    lines += compile_section(df)
    lines += limit_section(df, inv)
    lines += simd_goals.report_lines(df)         # issue 23 (bench/test_simd.py)
    lines += _skips_md(skips, "test_inverse")
    _plot_scaling(inv[inv["topology"] == "chain"], png)
    lines += ["", f"![scaling]({png.name})"]
    return "\n".join(lines) + "\n"


def _plot_scaling(chains: pd.DataFrame, png: Path) -> None:
    methods = sorted(chains["method"].unique())

    def draw(ax, dim):
        for (method, batched), g in chains[chains["dim"] == dim].groupby(["method", "batched"]):
            g = g.sort_values("n")
            st = _style(method, methods)
            ax.plot(g["n"], g["us_per_sample"] * 1e-6, marker="o" if batched else "x",
                    ls=st["ls"] if batched else ":", color=st["color"], ms=5,
                    label=f"{method} ({'batched' if batched else 'per call'})")

    _log_log_by_dim(png, draw, "number of links n", "seconds per sample (median)",
                    "Inverse dynamics: cost against n", panel_title="{dim}D serial chains",
                    note="Colour: the method (as in every figure); line: numba kernel solid, numpy kernel dashed, "
                         "others dash-dot; o = batched (per sample of one batched call), x and dotted = one sample "
                         "per call.")


# ----------------------------------------------------------------------------- paper table
def paper_table(df: pd.DataFrame, skips: list[dict], command: str) -> str:
    lines = ["# The paper's timing table, reproduced", "", provenance(command), "",
             "Seconds to *compose* the equations of motion (symbolic). The paper used Mathematica; we use sympy. "
             "Every row of one model produces the same equations, and the benchmark checks it before timing "
             "counts (`bench/test_compose.py`).", ""]
    comp = df[df["group"].str.startswith("compose")] if not df.empty else df
    if comp.empty:
        lines.append("No composition rows in this run.")
        return "\n".join(lines + _skips_md(skips, "test_compose")) + "\n"
    piv = comp.pivot_table(index=["dim", "topology", "n"], columns="method", values="median", aggfunc="min")
    f = lambda x: "-" if x is None or (isinstance(x, float) and np.isnan(x)) else f"{x:.3g}"
    get = lambda row, k: row.get(k) if row is not None else None
    lines += ["## Side by side with the paper", "",
              "Ours: `lagrange` is our Lagrange II derivation in sympy's polynomial ring, `lagrange-expr` the "
              "textbook route with `sympy.diff`/`expand`, `LagrangesMethod` sympy.physics.mechanics; "
              "`matrix` and `recurrence` the paper's methods composed from their closed forms. The ratio column "
              "compares like with like: the paper's Lagrange/matrix against our LagrangesMethod/matrix.", "",
              "| model | paper: Lagrange II | paper: matrix | paper: recurrence | ours: lagrange | ours: lagrange-expr | "
              "ours: LagrangesMethod | ours: matrix | ours: recurrence | paper: Lagrange/matrix | "
              "ours: LagrangesMethod/matrix |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for dim, n, topo, pl, pm, pr in PAPER_TABLE:
        row = piv.loc[(dim, topo, n)] if (dim, topo, n) in piv.index else None
        ol, oe, osl, om, orr = (get(row, k) for k in ("lagrange", "lagrange-expr", "sympy-lagrangesmethod",
                                                       "matrix", "recurrence"))
        lines.append(f"| {dim}D, {n} link(s) | {pl} | {pm} | {f(pr)} | {f(ol)} | {f(oe)} | {f(osl)} | {f(om)} | "
                     f"{f(orr)} | {pl / pm:.3g} | {f(osl / om if osl and om else None)} |")
    lines += ["", "## Every row we measured (seconds, median)", "",
              "| model | " + " | ".join(piv.columns) + " | fastest peer / matrix |",
              "|---|" + "---|" * (len(piv.columns) + 1)]
    peers = [c for c in piv.columns if c in ("lagrange", "lagrange-expr", "sympy-lagrangesmethod", "sympy-kanesmethod")]
    for (dim, topo, n), row in piv.iterrows():
        ratio = min((row[p] for p in peers if not np.isnan(row[p])), default=np.nan) / row.get("matrix", np.nan)
        lines.append(f"| {dim}D {topo} n={n} | " + " | ".join(f(row[c]) for c in piv.columns) + f" | {f(ratio)} |")
    lines += _skips_md(skips, "test_compose")
    lines += ["", "## Verdict on the paper's claim", ""] + _verdict(piv, peers)
    return "\n".join(lines) + "\n"


def _verdict(piv: pd.DataFrame, peers: list[str]) -> list[str]:
    out = []
    if "matrix" not in piv.columns or not peers:
        return ["Not enough rows to judge."]
    for (dim, topo), sub in piv.groupby(level=["dim", "topology"]):
        sub = sub.droplevel(["dim", "topology"])
        for peer in ("sympy-lagrangesmethod", "lagrange-expr", "lagrange"):
            if peer not in sub:
                continue
            r = (sub[peer] / sub["matrix"]).dropna()
            if len(r) < 2:
                continue
            grows = bool(np.all(np.diff(r.to_numpy()) > 0))
            out.append(f"- {dim}D, {topo} models, {peer}/matrix by n: " + ", ".join(f"n={n}: {v:.3g}" for n, v in r.items())
                       + (" - grows with n." if grows else " - does not grow monotonically."))
    for dim in (2, 3):
        for peer in ("sympy-lagrangesmethod", "lagrange-expr"):
            if peer in piv.columns and (dim, "chain", 2) in piv.index:
                r = piv.loc[(dim, "chain", 2), peer] / piv.loc[(dim, "chain", 2), "matrix"]
                out.append(f"- {peer}/matrix at n=2: {r:.3g} in {dim}D")
    # rows where a peer finished (the full profile composes 3D n = 10..50 by matrix and recurrence alone)
    rows2 = [(k, row) for k, row in piv.iterrows()
             if k[2] >= 2 and not np.isnan(row["matrix"]) and any(not np.isnan(row[p]) for p in peers)]
    slower = all(min(row[p] for p in peers if not np.isnan(row[p])) > row["matrix"] for _, row in rows2)
    out.append("- Goal: the matrix method composes faster than every Lagrange/Kane peer at every n >= 2: "
               + ("met." if slower else "**missed** (see the table)."))
    if "sympy-lagrangesmethod" in piv.columns and (3, "chain", 2) in piv.index:
        ratio = piv.loc[(3, "chain", 2), "sympy-lagrangesmethod"] / piv.loc[(3, "chain", 2), "matrix"]
        out.append(f"- Goal: matrix at least {GOAL_RATIO_3D2:g}x faster than LagrangesMethod at 3D n=2: {ratio:.3g}x "
                   + ("(met)." if ratio >= GOAL_RATIO_3D2 else f"(**missed** by a factor {GOAL_RATIO_3D2 / ratio:.3g})."))
    if (3, "chain", 5) in piv.index:
        t = piv.loc[(3, "chain", 5), "matrix"]
        out.append(f"- Goal: composing 3D n=5 by the matrix method in at most {GOAL_COMPOSE_3D5_S * 1e3:g} ms: "
                   f"{t * 1e3:.3g} ms " + ("(met)." if t <= GOAL_COMPOSE_3D5_S else
                                            f"(**missed** by {(t - GOAL_COMPOSE_3D5_S) * 1e3:.3g} ms)."))
    else:
        out.append("- Goal 3D n=5 in at most 50 ms: not measured in this sweep (`exo-bench bench --full`).")
    out.append("- The paper: the gap grows with n and with the move to 3D. Compare the ratios above across n and "
               "between the 2D and 3D rows at equal n.")
    return out


GOAL_WRAPPER_US = 2.0        # a prepared model's own per-call cost with check=False (issue 11)


def goals(df: pd.DataFrame) -> list[str]:
    """The numeric goals for the five-link 3D model, met or missed by how much; ratios only
    between rows of this run (one host)."""
    inv = _inverse(df)
    if inv.empty:
        return []
    out = ["## Goals for the five-link 3D model", "",
           "Ratios compare rows of this one run on this one machine.", ""]
    exo = inv[(inv["mechanism"] == "exo5-3d") & inv["batched"]].set_index("method")
    names = [m for m in exo.index if _base(m) in ("matrix-factored", "matrix")]
    if not names:
        out.append("- `matrix-factored` and `matrix` have no batched row in this run.")
    for name in names:
        m = exo.loc[name]
        us, err = m["us_per_sample"], m["max_rel_err"]
        out.append(f"- `{name}`, batched, at most {GOAL_US_PER_SAMPLE} us/sample: {us:.3g} us " +
                   ("(met)" if us <= GOAL_US_PER_SAMPLE else f"(missed, x{us / GOAL_US_PER_SAMPLE:.2g})"))
        if "pinocchio-parallel" in exo.index:
            rp = exo.loc["pinocchio-parallel", "us_per_sample"]
            out.append(f"  - against rneaInParallel ({rp:.3g} us/sample): {rp / us:.3g}x faster" if us <= rp
                       else f"  - against rneaInParallel ({rp:.3g} us/sample): {us / rp:.3g}x slower")
        out.append(f"  - error at most {GOAL_ERR:g} against the reference: {err:.1e} " + ("(met)" if err <= GOAL_ERR else "(missed)"))
    per = inv[(inv["mechanism"] == "exo5-3d") & ~inv["batched"] & inv["group"].str.startswith("inverse")]
    per = per.set_index("method")["median"] * 1e6
    if "pin.rnea (bare)" in per.index:
        bare = per["pin.rnea (bare)"]
        out += ["", f"Per call (one sample, `check=False`), against bare `pin.rnea` on the same model ({bare:.3g} us):", ""]
        for name in [m for m in per.index if m != "pin.rnea (bare)"]:
            out.append(f"- `{name}`: {per[name]:.3g} us, {per[name] / bare:.3g}x bare `pin.rnea`")
    out += wrapper_costs(df)
    return out


def wrapper_costs(df: pd.DataFrame) -> list[str]:
    """The prepared model's own per-call cost (group ``wrapper-exo5-3d``): the median of a call with
    ``check=False`` minus the median of the kernel it calls on the same arrays. ``(wrapper alone)`` has
    a kernel that does no work, so its difference is the wrapper's cost without a kernel's noise; for
    the real methods the difference is within the interquartile ranges of the two timings."""
    if df.empty or "part" not in df:
        return []
    w = df[df["group"] == "wrapper-exo5-3d"]
    if w.empty:
        return []
    out = ["", f"The prepared model's own cost per call on exo5-3d (`check=False`; goal at most {GOAL_WRAPPER_US:g} us). "
           "The wrapper is the same code for every method; `(wrapper alone)` measures it with a kernel that does "
           "no work, the other rows show it beside real kernels, whose timing noise (IQR) is given.", "",
           "| method | call (us) | kernel (us) | call - kernel (us) | IQR of call, kernel (us) | goal |",
           "|---|---|---|---|---|---|"]
    for method, g in w.groupby("method"):
        parts = g.set_index("part")
        if {"call", "kernel"} <= set(parts.index):
            c, k = parts.loc["call"], parts.loc["kernel"]
            cost = (c["median"] - k["median"]) * 1e6
            noise = (c["iqr"] + k["iqr"]) * 1e6
            verdict = ("met" if cost <= GOAL_WRAPPER_US else "missed") if method == "(wrapper alone)" else (
                "within noise" if abs(cost - 0) <= noise + GOAL_WRAPPER_US else "above noise")
            out.append(f"| {method} | {c['median'] * 1e6:.3g} | {k['median'] * 1e6:.3g} | {cost:.2g} | "
                       f"{c['iqr'] * 1e6:.2g}, {k['iqr'] * 1e6:.2g} | {verdict} |")
    return out


README_START, README_END = "<!-- paper-table:start -->", "<!-- paper-table:end -->"


def readme_with_table(readme: str, table_md: str, command: str) -> str:
    """The README with the side-by-side table of ``paper_table.md`` between its markers."""
    if README_START not in readme or README_END not in readme:
        return readme
    lines = table_md.splitlines()
    k = lines.index("## Side by side with the paper")
    block = [ln for ln in lines[k + 1:] if ln.startswith("|")]
    block = block[:2 + len(PAPER_TABLE)]
    from exo_bench.bench.reporting import machine_info
    info = machine_info()
    body = "\n".join([f"_Inserted by `{command}` on {info['date (UTC)']} UTC ({info['cpu']}); "
                       "seconds to compose the equations; details in [reports/paper_table.md](reports/paper_table.md)._",
                       "", *block])
    head, rest = readme.split(README_START, 1)
    _, tail = rest.split(README_END, 1)
    return f"{head}{README_START}\n{body}\n{README_END}{tail}"


def _strip_raw_timings(path: Path) -> None:
    """Drop the per-round timing lists (megabytes for the per-call rows); the statistics stay."""
    data = json.loads(path.read_text())
    for b in data.get("benchmarks", []):
        b.get("stats", {}).pop("data", None)
    atomic_write(path, json.dumps(data, indent=1))


REPORT_FILES = ("paper_table.md", "error_vs_runtime.md", "error_vs_runtime.png", "scaling.md", "scaling.png")


def report_names(out: Path, sweep: str) -> dict[str, str]:
    """The file name each report takes in ``out``. A quick run never replaces what a full run
    wrote: when ``out``'s runs.json says a report came from ``exo-bench bench --full`` (or ``run
    --full``), a quick run writes its reports beside them as ``<name>-quick.<ext>`` instead."""
    from exo_bench.bench.output_files import narrower_names

    return narrower_names(out, REPORT_FILES, sweep == "full")


def write_reports(bjson: Path, sjson: Path, staging: Path, out: Path, sweep: str, command: str,
                  update_readme: bool = False, published_to: Path | None = None) -> list[Path]:
    """Every report of the benchmark suite from its pytest-benchmark JSON ``bjson`` and the skip
    reasons ``sjson`` (both in ``staging``), published into ``out`` together; the README's paper
    table only with ``update_readme``. Used by the serial run and by the Dask sweep alike.
    ``published_to``: the folder these files finally land in when ``out`` is itself a staging
    folder (the main job's), whose runs.json decides :func:`report_names`."""
    df, skips, _ = load(bjson, sjson)
    _strip_raw_timings(bjson)
    names = report_names(Path(published_to) if published_to else out, sweep)
    if names["scaling.md"] != "scaling.md":
        print(f"{out}: the benchmark reports there come from a full run; this {sweep} run writes "
              f"{', '.join(v for v in names.values() if v.endswith('.md'))} beside them", flush=True)
    st = {n: staging / v for n, v in names.items()}
    text = paper_table(df, skips, command)
    atomic_write(st["paper_table.md"], text)
    inv = _inverse(df)
    g12 = goals_issue12(inv, skips) if not inv.empty and "topology" in inv else []
    atomic_write(st["error_vs_runtime.md"], error_vs_runtime(df, skips, command, st["error_vs_runtime.png"])
                 + "\n" + "\n".join(goals(df)) + "\n\n" + "\n".join(g12) + "\n")
    atomic_write(st["scaling.md"], scaling(df, skips, command, st["scaling.png"]))
    published = publish([*st.values(), bjson], out)
    for p in published:
        print(f"wrote {p}")
    if update_readme and names["paper_table.md"] == "paper_table.md" and (REPO / "README.md").exists():
        readme = (REPO / "README.md").read_text()
        updated = readme_with_table(readme, text, command)
        if updated != readme:
            atomic_write(REPO / "README.md", updated)
            print(f"updated the paper table in {REPO / 'README.md'}")
    return published


def run(args) -> int:
    full = bool(getattr(args, "full", False))
    sweep = "full" if full else "quick"
    out = (Path(args.reports) if getattr(args, "reports", None) else REPORTS).resolve()
    command = "exo-bench bench" + (" --full" if full else "")
    with staging_dir(out) as st:
        bjson, sjson = st / f"benchmarks-{sweep}.json", st / "skips.json"
        cmd = [sys.executable, "-m", "pytest", str(REPO / "bench"), "-q", "-p", "no:cacheprovider",
               "--benchmark-enable", f"--benchmark-json={bjson}", f"--skips-json={sjson}", f"--sweep={sweep}",
               "--benchmark-columns=min,median,rounds"]
        print("running:", " ".join(cmd[2:]), flush=True)
        r = subprocess.run(cmd, cwd=REPO)
        if r.returncode not in (0,) or not bjson.exists():
            raise ValueError(f"benchmark suite failed (pytest exit code {r.returncode}); no report written")
        write_reports(bjson, sjson, st, out, sweep, command, bool(getattr(args, "update_readme", False)),
                      getattr(args, "published_to", None))
    return 0
