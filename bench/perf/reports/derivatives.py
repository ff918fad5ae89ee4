"""``derivatives.md`` and ``.png``: issue 36's derivatives benchmark, error against run time, and its goals.

Made from the rows of bench/test_derivatives.py (groups ``derivatives-*``) in one pytest-benchmark
JSON, i.e. one process: every ratio below divides two timings of that process. ``exo-bench bench``
writes it beside the other benchmark reports (:mod:`~exo_bench.bench.perf.reports.benchmark_reports`);
``python -m exo_bench.bench.perf.reports.derivatives BENCH_JSON --skips SKIPS_JSON --out DIR --sweep
quick|full --command TEXT [--load TEXT]`` writes it from a JSON of those rows alone.

The goals (issue 36), each from measured rows, stated as met, not met, or not judged (a row missing):

* exo5-3d, batched dtau/d(q, qd) per sample <= 10x batched ID per sample (the fastest analytic kernel);
* exo5-3d, one sample: dtau/d(q, qd) <= 1.0x a bare ``pin.rnea`` call;
* exo5-3d, forward-dynamics derivatives per sample (``model.derivatives`` of newton-euler) <= 25x
  batched forward dynamics per sample;
* 3D chain of 100 links: dtau/d(q, qd) <= 0.5 ms per sample (the fastest analytic kernel there);
* growth exponent of that kernel's time per sample over n = 10 to 300 <= 2.1 (least squares of log t
  on log n over the chains measured; judged only when they span 10 to 300);
* exo5-3d, batched JVP and VJP of inverse dynamics per sample (``model.derivatives``' directional
  derivatives) <= 3x batched ID per sample: the issue's "about 2-3x the cost of ID", its upper end.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from exo_bench.bench.perf.reports.loading import _skips_md
from exo_bench.bench.perf.reports.scaling import fit_exponent

ID, FD, RNEA = "ID (newton-euler batched)", "FD (newton-euler batched)", "pin.rnea (bare)"
CASADI, PROVIDER, ONE = "casadi AD", "model.derivatives (newton-euler)", "analytic (auto)"
#: The products' rows, by prefix: their names end with the kernel that ran ("JVP (model.derivatives, simd)").
JVP, VJP = "JVP (model.derivatives", "VJP (model.derivatives"
FLOOR = "write floor (fill)"


def rows(df: pd.DataFrame) -> pd.DataFrame:
    """The derivative rows with ``us`` (microseconds per sample of the fastest round) and
    ``us_median`` (of the median round). The goals use the fastest round: on a shared machine it
    estimates the uncontended cost, where the median moves with the other processes' load (the
    same exo5-3d one-sample row gave medians of 52 and 58 us in two runs, fastest rounds of 6.8 and 6.1)."""
    if df is None or df.empty or "group" not in df:
        return pd.DataFrame()
    d = df[df["group"].astype(str).str.startswith("derivatives-")].copy()
    if d.empty:
        return d
    d["us"] = d["min"] / d["samples"].astype(float) * 1e6
    d["us_median"] = d["median"] / d["samples"].astype(float) * 1e6
    return d


def _pick(d: pd.DataFrame, group: str, mech: str, method: str | None = None, prefix: str | None = None):
    g = d[(d["group"] == f"derivatives-{group}") & (d["mechanism"] == mech)]
    g = g[g["method"] == method] if method else g[g["method"].astype(str).str.startswith(prefix or "")]
    return None if g.empty else g.sort_values("us").iloc[0]


def _verdict(value: float | None, target: float) -> str:
    if value is None or not math.isfinite(value):
        return "not judged"
    return "**met**" if value <= target else "**not met**"


def _ratio(add, goal: str, target: float, num, den, den_name: str, note: str = "") -> None:
    """A goal that is the ratio of two rows' times per sample (not judged when one is missing)."""
    if num is None or den is None:
        add(goal, target, None, f"no row of {'the derivatives' if num is None else den_name} in this run")
        return
    r = num["us"] / den["us"]
    add(goal, target, r, f"{r:.2f}x: {num['method']} {num['us']:.3g} us / {den_name} {den['us']:.3g} us{note}")


def goals(df: pd.DataFrame) -> list[dict]:
    """Each goal: ``goal``, ``target``, ``value`` (None when a row is missing), ``verdict``, ``measured`` (text)."""
    d = rows(df)
    out: list[dict] = []

    def add(goal, target, value, measured):
        out.append(dict(goal=goal, target=target, value=value, verdict=_verdict(value, target), measured=measured))

    if d.empty:
        return out
    best = _pick(d, "inverse-batched", "exo5-3d", prefix="analytic")
    base = _pick(d, "inverse-batched", "exo5-3d", ID)
    cas = _pick(d, "inverse-batched", "exo5-3d", CASADI)
    now = f"; CasADi (today's path) {cas['us'] / base['us']:.0f}x" if cas is not None and base is not None else ""
    _ratio(add, "exo5-3d batched dtau/d(q,qd) / batched ID, per sample", 10.0, best, base, "ID", now)
    one, rnea = _pick(d, "inverse-one-sample", "exo5-3d", ONE), _pick(d, "inverse-one-sample", "exo5-3d", RNEA)
    _ratio(add, "exo5-3d one sample dtau/d(q,qd) / bare pin.rnea", 1.0, one, rnea, "pin.rnea")
    fwd, fd = _pick(d, "forward-batched", "exo5-3d", PROVIDER), _pick(d, "forward-batched", "exo5-3d", FD)
    _ratio(add, "exo5-3d forward derivatives / batched FD, per sample", 25.0, fwd, fd, "FD")
    c100 = _pick(d, "inverse-batched", "chain100-3d", prefix="analytic")
    f100 = _pick(d, "inverse-batched", "chain100-3d", FLOOR)
    if c100 is not None:
        floor = "" if f100 is None else f"; write floor {f100['us'] / 1e3:.3g} ms ({FLOOR}: the output's bytes)"
        add(
            "chain 100 (3D) dtau/d(q,qd) per sample, ms",
            0.5,
            c100["us"] / 1e3,
            f"{c100['us'] / 1e3:.3g} ms ({c100['method']}){floor}",
        )
    else:
        add(
            "chain 100 (3D) dtau/d(q,qd) per sample, ms",
            0.5,
            None,
            "no chain-100 row in this run (`exo-bench bench --full`)",
        )
    kernel = c100["method"] if c100 is not None else (best["method"] if best is not None else None)
    ch = d[(d["group"] == "derivatives-inverse-batched") & (d["topology"] == "chain") & (d["method"] == kernel)]
    ns = ch["n"].to_numpy(float)
    p = fit_exponent(ns, ch["us"].to_numpy(float)) if len(ch) >= 2 else float("nan")
    span = f"n = {int(ns.min())}..{int(ns.max())}" if len(ns) else "no chain rows"
    judged = len(ns) >= 2 and ns.min() <= 10 and ns.max() >= 300
    add("growth exponent over n = 10..300", 2.1, p if judged else None,
        f"{p:.2f} over {span} ({kernel})" + ("" if judged else ": the goal's range is not covered")
        + _floor_exponent(d))  # fmt: skip
    for product in (JVP, VJP):
        row = _pick(d, "products-batched", "exo5-3d", prefix=product)
        _ratio(add, f"exo5-3d batched {product[:3]} / batched ID, per sample", 3.0, row, base, "ID")
    return out


def _floor_exponent(d: pd.DataFrame) -> str:
    """The write floor's own exponent over the same chains, and its time at the largest n: where the
    output leaves the caches (3 dof^2 8 bytes a sample: 2.2 MB at n = 100, 19 MB at 300), writing it
    grows faster than n^2, and no kernel can beat the floor."""
    f = d[(d["group"] == "derivatives-inverse-batched") & (d["topology"] == "chain") & (d["method"] == FLOOR)]
    if len(f) < 2:
        return ""
    big = f.sort_values("n").iloc[-1]
    p = fit_exponent(f["n"].to_numpy(float), f["us"].to_numpy(float))
    return f"; the write floor ({FLOOR}) grows as n^{p:.2f} and takes {big['us'] / 1e3:.3g} ms at n = {int(big['n'])}"


def _fmt(x) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return "inf" if math.isinf(x) else f"{x:.1e}"


def _reference(text) -> str:
    return "baseline (no derivatives)" if not isinstance(text, str) else text


def _table(d: pd.DataFrame, group: str, title: str, per: str) -> list[str]:
    g = d[d["group"] == f"derivatives-{group}"].sort_values(["n", "us"])
    if g.empty:
        return []
    head = (
        f"| model | method | samples | {per} | median | max rel error | error / (eps scale) | prepare s | reference |"
    )
    lines = [f"### {title}", "", head, "|---|---|---|---|---|---|---|---|---|"]
    for _, r in g.iterrows():
        lines.append(
            f"| {r['mechanism']} | {r['method']} | {int(r['samples'])} | {r['us']:.3g} | {r['us_median']:.3g} | "
            f"{_fmt(r.get('max_rel_err'))} | {_fmt(r.get('err_ratio'))} | {_fmt(r.get('prepare_s'))} | "
            f"{_reference(r.get('reference'))} |"
        )
    return lines + [""]


def derivatives_report(
    df: pd.DataFrame,
    skips: list[dict],
    command: str,
    png: Path | None,
    *,
    header: str | None = None,
    clock: Callable[[], _dt.datetime] | None = None,
    load: str = "",
) -> str:
    """The report's Markdown; draws ``png`` when there are rows. ``header`` replaces the provenance
    block and ``clock`` the wall clock of the date line (tests pass fakes); ``load`` says what else ran
    on the machine (``--load`` of :func:`main`)."""
    if header is None:
        from exo_bench.bench.output.provenance import provenance

        header = provenance(command)
    now = (clock or (lambda: _dt.datetime.now(_dt.UTC)))()
    note = f" ({load})" if load else ""
    lines = ["# Derivatives of the equations of motion: ours and the peers', error against run time", "", header]
    d = rows(df)
    if d.empty:
        return "\n".join(lines + ["No derivative rows in this run (bench/test_derivatives.py)."]) + "\n"
    lines += [
        f"Measured on {now:%Y-%m-%d} (UTC) in one pytest process{note}. Times are those of the fastest round "
        "of each row (its median beside it): on a shared machine the fastest round estimates the uncontended "
        "cost. The ratios divide timings of that one process. Errors are against the 50-digit reference "
        "of the derivatives "
        "(exo_bench.lagrange.derivative_reference: d'Alembert on the point masses, exact dual numbers at 50 "
        "digits, MPFR through gmpy2; inverse derivatives to n = 100, forward ones to n = 20, whose 50-digit "
        "solve grows as dof^3), on the first sample(s) of each batch; 'error / (eps scale)' is in units of its "
        "error model.",
        "",
        "## Goals (issue 36)",
        "",
        "| goal | target | measured | verdict |",
        "|---|---|---|---|",
    ]
    lines += [f"| {g['goal']} | <= {g['target']:g} | {g['measured']} | {g['verdict']} |" for g in goals(df)]
    lines += ["", "## Rows", ""]
    lines += _table(d, "inverse-batched", "Inverse dynamics derivatives (dtau/dq, dtau/dqd, M), batched", "us/sample")
    lines += _table(d, "inverse-one-sample", "One sample per call", "us/call")
    lines += _table(
        d, "forward-batched", "Forward dynamics derivatives (dqdd/dq, dqdd/dqd, M^-1), batched", "us/sample"
    )
    lines += _table(
        d, "products-batched", "Directional derivatives of inverse dynamics (JVP, VJP), batched", "us/sample"
    )
    if "engine_warnings" in d:
        warned = d[d["engine_warnings"].notna()]
        lines += ["Warnings the engines printed during a row (kept out of the timings' console):", ""]
        lines += [f"- {r['method']} on {r['mechanism']}: {r['engine_warnings']}" for _, r in warned.iterrows()]
    lines += _skips_md(skips, "test_derivatives.py")
    if png is not None:
        _plot(d, png)
        lines += ["", f"![error against run time]({png.name})"]
    return "\n".join(lines) + "\n"


def _plot(d: pd.DataFrame, png: Path) -> None:
    from matplotlib.figure import Figure

    from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT

    from exo_bench.bench.output.provenance import save_figure

    floor = 1e-17
    fig = Figure(figsize=(15, 6.5), layout="constrained")
    axes = fig.subplots(1, 2, sharey=True)
    drawn = d[d["max_rel_err"].notna()] if "max_rel_err" in d else d.iloc[:0]  # rows with a reference
    methods = sorted(drawn["method"].astype(str).unique())
    for ax, (group, title) in zip(
        axes, (("inverse-batched", "inverse dynamics"), ("forward-batched", "forward dynamics"))
    ):
        g = d[(d["group"] == f"derivatives-{group}") & d["max_rel_err"].notna()] if "max_rel_err" in d else d.iloc[:0]
        for method, m in g.groupby("method"):
            k = methods.index(str(method))  # one colour and marker per row name, in both panels
            ax.scatter(m["us"] * 1e-6, np.maximum(m["max_rel_err"].astype(float), floor), label=method,
                       color=f"C{k % 10}", marker="osD^v<>ph*"[k % 10], edgecolors="black", linewidths=0.4,
                       s=12 + 14 * np.log2(m["n"].to_numpy(float) + 1), alpha=0.85)  # fmt: skip
        if not g.empty:  # limits from the data, before the log scale (one point alone gives a singular range)
            x = g["us"].to_numpy(float) * 1e-6
            ax.set_xlim(x.min() / 2, x.max() * 2)
            ax.set_ylim(floor / 2, max(1.0, float(np.nanmax(g["max_rel_err"].astype(float))) * 2))
        else:
            ax.text(0.5, 0.5, "no rows with a reference", transform=ax.transAxes, ha="center")
        ax.set(xscale="log", yscale="log")
        ax.set_xlabel("seconds per sample (batched, fastest round)", fontsize=TEXT_PT)
        ax.set_title(f"derivatives of {title}", fontsize=TITLE_PT)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=TEXT_PT - 2, loc="best")
    axes[0].set_ylabel(f"max relative error vs 50-digit reference (floored at {floor:g})", fontsize=TEXT_PT)
    fig.suptitle("Derivatives: error against run time (marker area grows with n)", fontsize=TITLE_PT + 1)
    save_figure(fig, png)


def main(argv: list[str] | None = None) -> int:
    from exo_bench.bench.output.files import quick_name
    from exo_bench.models.files import atomic_write
    from exo_bench.bench.perf.reports.loading import load

    p = argparse.ArgumentParser(description="write derivatives.md and .png from bench/test_derivatives.py's JSON")
    p.add_argument("json")
    p.add_argument("--skips", default=None)
    p.add_argument("--out", required=True)
    p.add_argument(
        "--sweep",
        choices=("quick", "full"),
        required=True,
        help="quick: derivatives-quick.md, as exo-bench bench names it",
    )
    p.add_argument("--command", required=True, help="what produced the JSON (said in the report)")
    p.add_argument("--load", default="", help="what else ran on the machine during the run (said in the report)")
    a = p.parse_args(argv)
    df, skips, _ = load(Path(a.json), Path(a.skips) if a.skips else None)
    out = Path(a.out)
    md, png = "derivatives.md", "derivatives.png"
    if a.sweep == "quick":  # as exo-bench bench names a quick run's reports beside a full run's
        md, png = quick_name(md), quick_name(png)
    atomic_write(out / md, derivatives_report(df, skips, a.command, out / png, load=a.load))
    print(f"wrote {out / md}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
