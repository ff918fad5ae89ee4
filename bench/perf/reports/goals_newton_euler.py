"""The scaling report's section on ``newton-euler`` (issue 22): its goals, met or not, with the
measured ratios, the forward-dynamics table and the memory figures (rows of one run only).

Goals, on 3D chains, from one run of the full sweep (``exo-bench bench --full``):

* the batched cost of ``newton-euler (numba)`` grows like n^p with p <= :data:`GOAL_EXPONENT` from
  n = 20 to n = 1000;
* it is at least :data:`GOAL_VS_FACTORED_100` x faster per sample than ``matrix-factored`` at
  n = 100 and :data:`GOAL_VS_FACTORED_1000` x at n = 1000, against that method's fastest kernel in
  the run (its numpy kernel, BLAS on the O(n^2) products, overtakes its numba kernel at large n);
* its forward dynamics at n = 100 is at least :data:`GOAL_FORWARD_VS_PIN` x faster per sample than
  Pinocchio's CRBA + Cholesky;
* n = 10,000 runs inverse and forward dynamics in under :data:`GOAL_MEMORY_MB` MB (the whole
  process's peak resident set, bench/test_forward_dynamics.py ``test_newton_euler_memory``).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

NE = "newton-euler (numba)"
PIN_FORWARD = "pinocchio (CRBA + Cholesky)"
GOAL_EXPONENT = 1.05
GOAL_VS_FACTORED_100 = 2.0
GOAL_VS_FACTORED_1000 = 20.0
GOAL_FORWARD_VS_PIN = 10.0
GOAL_MEMORY_MB = 1000.0
EXPONENT_RANGE = (20, 1000)


def _met(ok: bool) -> str:
    return "**met**" if ok else "**not met**"


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
