"""``scaling.md`` and ``.png``: the speed goals met or not, the per-call and batched tables, fitted growth
exponents, the crossover n against Pinocchio, the kernels' compile time, where the limit is, and the
section on ``newton-euler``'s goals (:func:`newton_euler_goals`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from exo_bench.api.methods import METHODS, known_wrong, matrix_family
from exo_bench.bench.output.provenance import provenance
from exo_bench.bench.perf.reports import goals_call_overhead, simd_goals
from exo_bench.bench.perf.reports.loading import _base, _inverse, _log_log_by_dim, _skips_md, _style


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


FAST = "matrix-factored (numba)"


PIN_BARE = "pin.rnea (bare)"


PYDY = "pydy-cython"


#: Issue 12's goals (ratios from one run on one machine).
GOAL12_PER_CALL_VS_RNEA = 0.5  # matrix-factored per call, exo5-3d, at most this x bare pin.rnea


GOAL12_US_PER_SAMPLE = 0.15  # matrix-factored batched, exo5-3d, 10,000 samples


GOAL12_VS_PIN_BATCHED = 30.0  # ... at least this much faster than Pinocchio's best batched path


GOAL12_REL_ERR = 1e-14  # every row, against the 50-digit reference


def _met(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


def _pin_best_batched(d: pd.DataFrame) -> pd.Series:
    """Pinocchio's fastest batched path per n (``pinocchio`` loop or ``pinocchio-parallel``), us/sample."""
    pin = d[d["method"].isin(["pinocchio", "pinocchio-parallel"])]
    return pin.groupby("n")["us_per_sample"].min()


def speed_goals(inv: pd.DataFrame, skips: list[dict]) -> list[str]:
    """Issue 12's goals, each met or not met with the measured ratio (rows of this run only)."""
    out = [
        "## Goals (issue 12)",
        "",
        "Ratios compare rows of this one run on this one machine (indicative where the machine was shared).",
        "",
    ]
    exo = inv[inv["mechanism"] == "exo5-3d"]
    per = exo[~exo["batched"]].set_index("method")["median"] * 1e6
    bat = exo[exo["batched"]].set_index("method")["us_per_sample"]
    if FAST in per.index and PIN_BARE in per.index:
        r = per[FAST] / per[PIN_BARE]
        out.append(
            f"- Per call, exo5-3d, `check=False`: `{FAST}` {per[FAST]:.3g} us, bare `pin.rnea` "
            f"{per[PIN_BARE]:.3g} us: {r:.2f}x, goal at most {GOAL12_PER_CALL_VS_RNEA}x: "
            f"{_met(r <= GOAL12_PER_CALL_VS_RNEA)}."
        )
    else:
        out.append(f"- Per call against bare `pin.rnea`: not measured in this run (`{FAST}` or `{PIN_BARE}` missing).")
    if FAST in per.index and PYDY in per.index:
        r = per[FAST] / per[PYDY]
        out.append(
            f"- Per call, exo5-3d: `{FAST}` {per[FAST]:.3g} us, PyDy's Cython code {per[PYDY]:.3g} us: "
            f"{r:.2f}x, goal at most 1x: {_met(r <= 1.0)}."
        )
    else:
        out.append(
            "- Per call against PyDy's Cython code: not measured in this run (PyDy row skipped: "
            "`pip install 'exo-bench[peers]'`)."
        )
    if FAST in bat.index:
        us = bat[FAST]
        samples = int(exo[exo["batched"] & (exo["method"] == FAST)]["samples"].iloc[0])
        out.append(
            f"- Batched, exo5-3d, {samples:,} samples: `{FAST}` {us:.3g} us/sample, goal at most "
            f"{GOAL12_US_PER_SAMPLE} us: {_met(us <= GOAL12_US_PER_SAMPLE)}"
            + ("" if samples >= 10_000 else " (quick profile: fewer samples than the goal's 10,000)")
            + "."
        )
        pin = {m: bat[m] for m in ("pinocchio", "pinocchio-parallel") if m in bat.index}
        if pin:
            best = min(pin, key=lambda m: pin[m])
            threads = exo[exo["batched"] & (exo["method"] == best)]["threads"].iloc[0] if "threads" in exo else ""
            r = pin[best] / us
            out.append(
                f"- Batched, exo5-3d: Pinocchio's best batched path `{best}`"
                + (f" ({threads} threads)" if best == "pinocchio-parallel" and threads != "" else "")
                + f" {pin[best]:.3g} us/sample, {r:.3g}x slower than `{FAST}`; goal at least "
                f"{GOAL12_VS_PIN_BATCHED:g}x: {_met(r >= GOAL12_VS_PIN_BATCHED)}."
            )
    else:
        out.append(f"- Batched, exo5-3d: no `{FAST}` row in this run.")
    big = (
        inv[inv["batched"] & (inv["dim"] == 3) & (inv["n"] == 100) & (inv["topology"] == "chain")]
        if "topology" in inv
        else inv.iloc[:0]
    )
    fam = [f"{m} ({METHODS[m].kernel_options[0]})" for m in matrix_family()]  # the default kernel's rows
    if big.empty:
        out.append("- n = 100 in 3D, batched: not in this profile (`exo-bench bench --full`).")
    else:
        done = set(big["method"])
        missing = [m for m in fam if m not in done]
        slow = sorted(m for m in set(inv["method"]) if _base(m) in matrix_family() and m not in fam and m not in done)
        out.append(
            f"- n = 100 in 3D, batched: every matrix-family method (compiled, the default kernel) finishes: "
            f"{_met(not missing)}"
            + (f" (skipped: {', '.join(missing)})" if missing else f" ({', '.join(fam)})")
            + (f"; over the time budget: {', '.join(slow)}" if slow else "")
            + "."
        )
    ok = inv[~(inv["method"].map(_base).isin(known_wrong()) & (inv["dim"] == 3) & (inv["n"] > 1))]
    worst = ok.loc[ok["max_rel_err"].idxmax()] if not ok.empty else None
    if worst is not None:
        over = ok[ok["max_rel_err"] > GOAL12_REL_ERR]
        out.append(
            f"- Error at most {GOAL12_REL_ERR:g} relative against the 50-digit reference on every row "
            f"(matrix-paper in 3D excepted: wrong by design): largest {worst['max_rel_err']:.1e} "
            f"(`{worst['method']}`, {worst['mechanism']}, {'batched' if worst['batched'] else 'per call'}): "
            f"{_met(over.empty)}" + ("" if over.empty else f" ({len(over)} rows above)") + "."
        )
    return out + [""]


def _table(sub: pd.DataFrame, value: str, cols: list, fmt=lambda v: f"{v:.3g}", exponent: bool = False) -> list[str]:
    """Rows: methods; columns ``(mechanism label, n)`` pairs in ``cols``."""
    head = "| method | " + " | ".join(c[0] for c in cols) + (" | exponent p |" if exponent else " |")
    lines = [head, "|---|" + "---|" * (len(cols) + (1 if exponent else 0))]
    for method, g in sub.groupby("method"):
        cells, ns, ts = [], [], []
        for _label, mech in cols:
            r = g[g["mechanism"] == mech]
            if r.empty:
                cells.append("skipped")
            else:
                v = float(r[value].iloc[0])
                cells.append(fmt(v))
                if mech.startswith("chain"):
                    ns.append(int(r["n"].iloc[0]))
                    ts.append(v)
        p = f" | {fit_exponent(np.array(ns, float), np.array(ts, float)):.2f}" if exponent else ""
        lines.append(f"| {method} | " + " | ".join(cells) + p + " |")
    return lines


def compile_section(df: pd.DataFrame) -> list[str]:
    c = df[df["group"] == "compile"] if not df.empty else df
    if c.empty or "compile" not in c:
        return []
    info = c.iloc[0]["compile"]
    out = [
        "## Compile time of the compiled kernels",
        "",
        "First call of each numba kernel on exo5-3d in a fresh process with an empty numba cache (compiling), "
        "and in a second process with that cache (loading the machine code): numba's on-disk cache means "
        "a user pays the compile once per machine (and after an edit of the kernel's file). The first kernel "
        "loaded in a process also pays numba's own start-up.",
        "",
        "| method | driver | first call, empty cache (s) | first call, from the cache (ms) |",
        "|---|---|---|---|",
    ]
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
    out = [
        "## Where the limit is",
        "",
        "One exo5-3d sample of the factored kernel (`matrix_method/numba_kernels/factored.py`), counted by running the "
        "kernel's own per-sample function on counting floats (`bench/perf/roofline.py`; the counting run gives the "
        "compiled kernel's forces bit for bit):",
        "",
        f"- {count['add']} additions/subtractions and {count['mul']} multiplications ({count['flops']} flops), "
        f"{count['trig']} transcendental calls (cos, sin).",
        f"- This CPU, one core, measured with numba loops compiled like the kernels (`bench/perf/roofline.py`): "
        f"{rates['scalar_flops_per_s'] / 1e9:.3g} Gflop/s scalar, {rates['simd_flops_per_s'] / 1e9:.3g} Gflop/s "
        f"SIMD (multiply-adds), {rates['sincos_per_s'] / 1e6:.3g} M angles/s for `cos` and `sin` of one angle "
        f"({1e9 / rates['sincos_per_s']:.3g} ns each pair).",
        f"- Estimate for one sample on one core: {est['scalar_s'] * 1e9:.3g} ns with the flops scalar, "
        f"{est['simd_s'] * 1e9:.3g} ns with the flops at the SIMD rate (of which {est['trig_s'] * 1e9:.3g} ns are "
        f"the {count['trig'] // 2} angles); on the {threads} threads numba uses, "
        f"{est['scalar_s'] / threads * 1e9:.3g} and {est['simd_s'] / threads * 1e9:.3g} ns per sample.",
    ]
    exo = inv[(inv["mechanism"] == "exo5-3d") & (inv["method"] == FAST)] if not inv.empty else inv
    bat, per = exo[exo["batched"]], exo[~exo["batched"]]
    if not bat.empty:
        us = float(bat["us_per_sample"].iloc[0])
        out.append(
            f"- Measured, batched on {threads} threads: {us * 1e3:.3g} ns per sample: "
            f"{us * 1e-6 / (est['scalar_s'] / threads):.2g}x the scalar estimate, "
            f"{us * 1e-6 / (est['simd_s'] / threads):.2g}x the SIMD estimate (on a machine shared with "
            "other jobs the threads do not get whole cores: compare with one core's estimate, "
            f"{us * 1e-6 / est['scalar_s']:.2g}x and {us * 1e-6 / est['simd_s']:.2g}x)."
        )
    if not per.empty:
        t = float(per["median"].iloc[0])
        out.append(
            f"- Measured per call (one sample, from Python): {t * 1e9:.3g} ns, {t / est['scalar_s']:.2g}x the "
            "scalar estimate: the rest is the call (numba's dispatch of the arrays, the model's method)."
        )
    return out + [""]


def scaling(df: pd.DataFrame, skips: list[dict], command: str, png: Path) -> str:
    inv = _inverse(df)
    lines = ["# Scaling with the number of links", "", provenance(command), ""]
    if inv.empty:  # a selection of rows (exo-bench bench --rows) may still hold issue 35's goals
        extra = goals_call_overhead.report_lines(df)
        return (
            "\n".join(lines + ["No numeric inverse-dynamics rows in this run.", *([""] + extra if extra else [])])
            + "\n"
        )
    if "topology" not in inv:
        inv["topology"] = np.where(inv["mechanism"].str.startswith("chain"), "chain", "exo5")
    lines += speed_goals(inv, skips)
    lines += newton_euler_goals(df)  # newton-euler's goals and forward table
    per = inv[~inv["batched"]].copy()
    per["us_per_call"] = per["median"] * 1e6
    if not per.empty:
        cols = [("exo5-3d", "exo5-3d")] + [
            (f"{d}D n={n}", f"chain{n}-{d}d")
            for d in (2, 3)
            for n in sorted(per[per["topology"] == "chain"]["n"].unique())
        ]
        lines += [
            "## Per call",
            "",
            "Microseconds per call, one sample, `check=False`, into a preallocated `out` "
            "(`pin.rnea (bare)`: Pinocchio's own cost on preallocated joint coordinates; `pydy-cython`: PyDy's "
            "Cython code of the same composed equations; `mujoco`, `drake`: the engines, what their rows time "
            "below). Models: exo5-3d and serial chains of n links.",
            "",
        ]
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
        lines += [
            "## Batched",
            "",
            f"Microseconds per sample, one call for {samples:,} samples along a smooth random "
            "motion; exponent p fits cost ~ n^p over the chains with n >= 2.",
            "",
        ]
        for dim in sorted(bat["dim"].unique()):
            d = bat[bat["dim"] == dim]
            cols = [(f"n={n}", f"chain{n}-{dim}d") for n in sorted(d[d["topology"] == "chain"]["n"].unique())]
            if dim == 3:
                cols = [("exo5-3d", "exo5-3d")] + cols
            lines += [f"### {dim}D", ""] + _table(d, "us_per_sample", cols, exponent=True) + [""]
    lines += [
        "## Crossover against Pinocchio",
        "",
        "The smallest n of the chains from which Pinocchio is faster than the row and stays faster "
        "(batched: Pinocchio's best batched path at each n; per call: bare `pin.rnea`).",
        "",
    ]
    for label, sub, pin_of in (
        ("batched", bat, _pin_best_batched),
        ("per call", per, lambda d: d[d["method"] == PIN_BARE].groupby("n")["us_per_call"].min()),
    ):
        chains = sub[sub["topology"] == "chain"] if not sub.empty else sub
        value = "us_per_sample" if label == "batched" else "us_per_call"
        for dim in sorted(chains["dim"].unique()) if not chains.empty else []:
            d = chains[chains["dim"] == dim]
            pin = pin_of(d)
            for m in sorted({m for m in d["method"] if _base(m) in matrix_family()}):
                mm = d[d["method"] == m].set_index("n")[value]
                if len(mm) and len(pin):
                    lines.append(f"- {dim}D, {label}, `{m}` against Pinocchio: crossover {crossover(mm, pin)}")
    lines.append("")
    from exo_bench.bench.perf.peers import engine_section  # the engines' rows and their ratios

    lines += engine_section(inv)
    lines += compile_section(df)
    lines += limit_section(df, inv)
    lines += simd_goals.report_lines(df)  # issue 23 (bench/test_simd.py)
    lines += goals_call_overhead.report_lines(df)  # issue 35 (bench/test_call_overhead.py)
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
            ax.plot(
                g["n"],
                g["us_per_sample"] * 1e-6,
                marker="o" if batched else "x",
                ls=st["ls"] if batched else ":",
                color=st["color"],
                ms=5,
                label=f"{method} ({'batched' if batched else 'per call'})",
            )

    _log_log_by_dim(
        png,
        draw,
        "number of links n",
        "seconds per sample (median)",
        "Inverse dynamics: cost against n",
        panel_title="{dim}D serial chains",
        note="Colour: the method (as in every figure); line: numba kernel solid, numpy kernel dashed, "
        "others dash-dot; o = batched (per sample of one batched call), x and dotted = one sample "
        "per call.",
    )


# The scaling report's section on ``newton-euler`` (issue 22): its goals, met or not, with the measured ratios,
# the forward-dynamics table and the memory figures (rows of one run only).

NE = "newton-euler (numba)"
PIN_FORWARD = "pinocchio (CRBA + Cholesky)"
GOAL_EXPONENT = 1.05
GOAL_VS_FACTORED_100 = 2.0
GOAL_VS_FACTORED_1000 = 20.0
GOAL_FORWARD_VS_PIN = 10.0
GOAL_MEMORY_MB = 1000.0
EXPONENT_RANGE = (20, 1000)


def _fit(n: np.ndarray, t: np.ndarray) -> float:
    return float(np.polyfit(np.log(n), np.log(t), 1)[0])


def _per_sample(df: pd.DataFrame, group_prefix: str) -> pd.DataFrame:
    if df.empty or "group" not in df:
        return pd.DataFrame()
    d = df[df["group"].astype(str).str.startswith(group_prefix)].copy()
    if d.empty:
        return d
    d["us_per_sample"] = d["median"] / d["samples"].astype(float) * 1e6
    return d[(d["dim"] == 3) & (d.get("topology", "chain") == "chain")] if "topology" in d else d


def newton_euler_goals(df: pd.DataFrame) -> list[str]:
    """The section's Markdown lines (empty when the run has no newton-euler row)."""
    inv = _per_sample(df, "inverse-batched")
    fwd = _per_sample(df, "forward-batched")
    if (inv.empty or NE not in set(inv["method"])) and fwd.empty:
        return []
    out = [
        "## Goals (issue 22): newton-euler, O(n) from M = J^T M_r J",
        "",
        "3D serial chains, batched, microseconds per sample; ratios compare rows of this one run.",
        "",
    ]
    ne = inv[inv["method"] == NE].groupby("n")["us_per_sample"].min() if not inv.empty else pd.Series(dtype=float)
    lo, hi = EXPONENT_RANGE
    sel = ne[(ne.index >= lo) & (ne.index <= hi)]
    if lo in sel.index and hi in sel.index:
        p = _fit(np.array(sel.index, float), sel.to_numpy())
        out.append(
            f"- Growth of `{NE}` from n = {lo} to {hi} ({len(sel)} points): p = {p:.2f}, goal at most "
            f"{GOAL_EXPONENT}: {_met(p <= GOAL_EXPONENT)}."
        )
    else:
        out.append(
            f"- Growth from n = {lo} to {hi}: not measured in this run (n = "
            f"{', '.join(map(str, sorted(ne.index))) or 'none'}; the full profile has it)."
        )
    facs = inv[inv["method"].astype(str).str.startswith("matrix-factored (")] if not inv.empty else inv
    for n, goal in ((100, GOAL_VS_FACTORED_100), (1000, GOAL_VS_FACTORED_1000)):
        at = facs[facs["n"] == n] if not facs.empty else facs
        if n in ne.index and not at.empty:
            # judged against matrix-factored's fastest kernel at this n (its numpy kernel wins at large n)
            kernels = at.groupby("method")["us_per_sample"].min().sort_values()
            best, t = str(kernels.index[0]), float(kernels.iloc[0])
            r = t / ne[n]
            others = "; ".join(f"`{m}` {v:.3g} us, {v / ne[n]:.3g}x" for m, v in kernels.iloc[1:].items())
            out.append(
                f"- n = {n}: `{NE}` {ne[n]:.3g} us per sample; `matrix-factored`'s fastest kernel here, `{best}`, "
                f"{t:.3g} us: {r:.3g}x faster, goal at least {goal:g}x: {_met(r >= goal)}"
                + (f" ({others})." if others else ".")
            )
        else:
            out.append(f"- n = {n} against `matrix-factored`: not measured in this run.")
    f = fwd.groupby(["method", "n"])["us_per_sample"].min() if not fwd.empty else pd.Series(dtype=float)
    if (NE, 100) in f.index and (PIN_FORWARD, 100) in f.index:
        r = f[(PIN_FORWARD, 100)] / f[(NE, 100)]
        out.append(
            f"- Forward dynamics, n = 100: `{PIN_FORWARD}` {f[(PIN_FORWARD, 100)]:.3g} us, `{NE}` "
            f"{f[(NE, 100)]:.3g} us per sample: {r:.3g}x faster, goal at least {GOAL_FORWARD_VS_PIN:g}x: "
            f"{_met(r >= GOAL_FORWARD_VS_PIN)}."
        )
    else:
        out.append("- Forward dynamics at n = 100 against Pinocchio CRBA + Cholesky: not measured in this run.")
    mem = df[df["group"].astype(str) == "memory-newton-euler"] if "group" in df else pd.DataFrame()
    big = mem[mem["n"] == 10_000] if not mem.empty else mem
    if not big.empty:
        mb = float(big["peak_rss_mb"].max())
        out.append(
            f"- n = 10,000 in 3D, inverse then forward dynamics ({int(big['samples'].iloc[0])} samples) in a "
            f"fresh process: peak resident set {mb:.0f} MB, goal under {GOAL_MEMORY_MB:g} MB: "
            f"{_met(mb < GOAL_MEMORY_MB)}."
        )
    else:
        done = ", ".join(f"n = {int(r.n)}: {r.peak_rss_mb:.0f} MB" for r in mem.itertuples()) if not mem.empty else ""
        out.append("- n = 10,000 in under 1 GB: not measured in this run" + (f" ({done})" if done else "") + ".")
    out.append("")
    if not fwd.empty:
        ns = sorted(fwd["n"].unique())
        out += [
            "### Forward dynamics per sample",
            "",
            "Microseconds per sample of one batched `forward_dynamics(q, qd, tau, check=False)` on 3D chains "
            "(bench/test_forward_dynamics.py; backward error asserted); last column: bytes per sample traced "
            "during the call (numpy's arrays, the result's 8 dof bytes included; numba's O(n) scratch per block "
            "is not traced) at the largest n of the row.",
            "",
            "| method | " + " | ".join(f"n={n}" for n in ns) + " | exponent p | bytes/sample |",
            "|---|" + "---|" * (len(ns) + 2),
        ]
        for m, g in fwd.groupby("method"):
            s = g.groupby("n")["us_per_sample"].min()
            cells = [f"{s[n]:.3g}" if n in s.index else "skipped" for n in ns]
            pts = s[s.index >= 2]
            growth = f"{_fit(np.array(pts.index, float), pts.to_numpy()):.2f}" if len(pts) >= 2 else ""
            last = g.loc[g["n"].idxmax()]
            bps = f"{float(last['traced_bytes_per_sample']):.3g}" if "traced_bytes_per_sample" in g else ""
            out.append(f"| {m} | " + " | ".join(cells) + f" | {growth} | {bps} |")
        out.append("")
    return out
