"""``exo-bench bench``: run the benchmark suite and generate its reports with pandas.

Reports (each says what produced it, on what machine and when):

* ``reports/paper_table.md``: the paper's Mathematica timings beside ours, our extra rows, ratios,
  and a verdict on the claim that the gap grows with n and with 3D;
* ``reports/error_vs_runtime.md`` and ``.png``: seconds per sample against error, per method and n;
* ``reports/scaling.md`` and ``.png``: cost against n with fitted growth exponents, and the n where
  RNEA overtakes the matrix method.

The raw pytest-benchmark JSON is kept beside them (``reports/benchmarks-<sweep>.json``).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

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
    lines += _skips_md(skips, "test_inverse_batched")
    _plot_error_vs_runtime(bat, png)
    lines += ["", f"![error against run time]({png.name})"]
    return "\n".join(lines) + "\n"


def _log_log_by_dim(png: Path, draw, xlabel: str, ylabel: str, title: str, panel_title: str = "{dim}D",
                    legend_size: int = 8) -> None:
    """One log-log panel per dimension (2D, 3D) sharing the y axis; ``draw(ax, dim)`` plots a panel."""
    from matplotlib.figure import Figure

    from exo_bench.bench.plots import save_figure

    fig = Figure(figsize=(12, 5))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, dim in zip(axes, (2, 3)):
        draw(ax, dim)
        ax.set_xscale("log"); ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_title(panel_title.format(dim=dim))
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(ylabel)
    axes[1].legend(fontsize=legend_size)
    fig.suptitle(title)
    fig.tight_layout()
    save_figure(fig, png)


def _plot_error_vs_runtime(bat: pd.DataFrame, png: Path) -> None:
    markers = dict(zip(sorted(bat["method"].unique()), "osD^v<>p*"))
    floor = 1e-17

    def draw(ax, dim):
        for method, g in bat[bat["dim"] == dim].groupby("method"):
            ax.scatter(g["us_per_sample"] * 1e-6, np.maximum(g["max_rel_err"], floor), marker=markers[method],
                       label=method, s=40)
            for _, r in g.iterrows():
                ax.annotate(f"n={r['n']}" + (" exo5" if r["mechanism"].startswith("exo5") else ""),
                            (r["us_per_sample"] * 1e-6, max(r["max_rel_err"], floor)), fontsize=6,
                            xytext=(3, 3), textcoords="offset points")

    _log_log_by_dim(png, draw, "seconds per sample (batched, median)",
                    f"max relative error vs 50-digit reference (floored at {floor:g})",
                    "Inverse dynamics: error against run time")


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
    return f"not within n <= {common[-1]}"


def scaling(df: pd.DataFrame, skips: list[dict], command: str, png: Path) -> str:
    inv = _inverse(df)
    lines = ["# Scaling with the number of links", "", provenance(command), ""]
    if inv.empty:
        return "\n".join(lines + ["No numeric inverse-dynamics rows in this run."]) + "\n"
    chains = inv[inv["mechanism"].str.startswith("chain")]
    lines += ["Median cost of inverse dynamics on serial chains of n links, per sample, batched (one call for "
              "all samples) and per call (one sample per call on a prepared model, `check=False`). "
              "Exponent p fits cost ~ n^p over n >= 2.", ""]
    for batched, label in ((True, "batched"), (False, "per call")):
        sub = chains[chains["batched"] == batched]
        if sub.empty:
            continue
        lines += [f"## {label}", "", "| dim | method | " + " | ".join(f"n={n}" for n in sorted(sub["n"].unique()))
                  + " | exponent p |", "|---|---|" + "---|" * (len(sub["n"].unique()) + 1)]
        for (dim, method), g in sub.groupby(["dim", "method"]):
            g = g.set_index("n")["us_per_sample"].sort_index()
            cells = [f"{g[n]:.3g}" if n in g.index else "skipped" for n in sorted(sub["n"].unique())]
            p = fit_exponent(g.index.to_numpy(float), g.to_numpy(float))
            lines.append(f"| {dim}D | {method} | " + " | ".join(cells) + f" | {p:.2f} |")
        lines.append("")
        lines.append("Microseconds per sample. Where RNEA overtakes the matrix method:")
        lines.append("")
        for dim in sorted(sub["dim"].unique()):
            d = sub[sub["dim"] == dim]
            for ours in ("matrix-factored", "matrix"):
                mm = d[d["method"] == ours].set_index("n")["us_per_sample"]
                for rnea in ("pinocchio", "pinocchio-parallel"):
                    r = d[d["method"] == rnea].set_index("n")["us_per_sample"]
                    if len(mm) and len(r):
                        lines.append(f"- {dim}D, {label}: `{rnea}` is faster than `{ours}` from {crossover(mm, r)}")
        lines.append("")
    lines += _skips_md(skips, "test_inverse")
    _plot_scaling(chains, png)
    lines += ["", f"![scaling]({png.name})"]
    return "\n".join(lines) + "\n"


def _plot_scaling(chains: pd.DataFrame, png: Path) -> None:
    colors = {m: f"C{k}" for k, m in enumerate(sorted(chains["method"].unique()))}

    def draw(ax, dim):
        for (method, batched), g in chains[chains["dim"] == dim].groupby(["method", "batched"]):
            g = g.sort_values("n")
            ax.plot(g["n"], g["us_per_sample"] * 1e-6, marker="o" if batched else "x", ls="-" if batched else ":",
                    color=colors[method], label=f"{method} ({'batched' if batched else 'per call'})")

    _log_log_by_dim(png, draw, "number of links n", "seconds per sample (median)",
                    "Inverse dynamics: cost against n", panel_title="{dim}D serial chains", legend_size=7)


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
    rows2 = [(k, row) for k, row in piv.iterrows() if k[2] >= 2]
    slower = all(min(row[p] for p in peers if not np.isnan(row[p])) > row["matrix"] for _, row in rows2
                 if not np.isnan(row["matrix"]))
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
    for name in ("matrix-factored", "matrix"):
        if name not in exo.index:
            out.append(f"- `{name}` has no batched row in this run.")
            continue
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
        df, skips, _ = load(bjson, sjson)
        _strip_raw_timings(bjson)
        files = []
        text = paper_table(df, skips, command)
        atomic_write(st / "paper_table.md", text); files.append(st / "paper_table.md")
        atomic_write(st / "error_vs_runtime.md", error_vs_runtime(df, skips, command, st / "error_vs_runtime.png")
                     + "\n" + "\n".join(goals(df)) + "\n")
        files += [st / "error_vs_runtime.md", st / "error_vs_runtime.png"]
        atomic_write(st / "scaling.md", scaling(df, skips, command, st / "scaling.png"))
        files += [st / "scaling.md", st / "scaling.png", bjson]
        for p in publish(files, out):
            print(f"wrote {p}")
        if getattr(args, "update_readme", False) and (REPO / "README.md").exists():
            readme = (REPO / "README.md").read_text()
            updated = readme_with_table(readme, text, command)
            if updated != readme:
                atomic_write(REPO / "README.md", updated)
                print(f"updated the paper table in {REPO / 'README.md'}")
    return 0
