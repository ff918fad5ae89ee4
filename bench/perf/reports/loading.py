"""What the benchmark reports share: the benchmark JSON as pandas frames (rows, skips and the machine; a
row name's method and kernel) and the figures' log-log panels by dimension and line styles."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from exo_bench.bench.perf.rows import check_ratio_groups


def load(json_path: Path, skips_path: Path | None = None) -> tuple[pd.DataFrame, list[dict], dict]:
    data = json.loads(Path(json_path).read_text())
    rows = []
    for b in data.get("benchmarks", []):
        info = dict(b.get("extra_info", {}))
        st = b["stats"]
        info.update(
            group=b["group"],
            name=b["name"],
            median=st["median"],
            min=st["min"],
            mean=st["mean"],
            rounds=st["rounds"],
            iqr=st.get("iqr", float("nan")),
        )
        rows.append(info)
    skips = json.loads(Path(skips_path).read_text()) if skips_path and Path(skips_path).exists() else []
    check_ratio_groups(pd.DataFrame(rows))  # never a ratio of timings from two hosts (bench/perf/rows.py)
    return pd.DataFrame(rows), skips, data.get("machine_info", {})


def _base(row_name: str) -> str:
    """The method of a row name (``"matrix-factored (numba)"`` -> ``"matrix-factored"``)."""
    return str(row_name).split(" (")[0]


def _kernel(row_name: str) -> str:
    """What the row name says in brackets after the method (``"matrix (numba)"`` -> ``"numba"``,
    ``"pin.rnea (bare)"`` -> ``"bare"``, ``"pinocchio"`` -> ``""``)."""
    return str(row_name)[len(_base(row_name)) :].strip(" ()")


def _inverse(df: pd.DataFrame) -> pd.DataFrame:
    if df.empty or "batched" not in df:
        return pd.DataFrame()
    inv = df[df["group"].str.startswith("inverse")].copy()
    inv["batched"] = inv["batched"].astype(bool)  # object dtype beside the compose rows; ~ needs bools
    inv["us_per_sample"] = inv["median"] / inv["samples"] * 1e6
    return inv


def _skips_md(skips: list[dict], prefix: str) -> list[str]:
    rel = [s for s in skips if prefix in s["nodeid"]]
    if not rel:
        return []
    out = ["", "Skipped rows (with the reason recorded by the benchmark):", ""]
    out += [f"- `{s['nodeid'].split('::')[-1]}`: {s['reason']}" for s in rel]
    return out


# What the benchmark figures share: log-log panels by dimension, and a row's colour (its method's) and line
# style (its kernel's).


def _log_log_by_dim(
    png: Path, draw, xlabel: str, ylabel: str, title: str, panel_title: str = "{dim}D", note: str = ""
) -> None:
    """One log-log panel per dimension (2D, 3D) sharing the y axis; ``draw(ax, dim)`` plots a panel.
    One legend for both panels, outside the data (right of them), and ``note`` under the panels."""
    from matplotlib.figure import Figure
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT

    from exo_bench.bench.output.provenance import save_figure

    layout = ConstrainedLayoutEngine()
    fig = Figure(figsize=(15, 6.5), layout=layout)
    axes = fig.subplots(1, 2, sharey=True)
    for ax, dim in zip(axes, (2, 3)):
        draw(ax, dim)
        ax.set_xscale("log")
        ax.set_yscale("log")
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
        layout.set(rect=(0, 0.06, 1, 0.94))
    fig.suptitle(title, fontsize=TITLE_PT + 1)
    save_figure(fig, png)


def _style(method: str, methods) -> dict:
    """Colour from the base method (the same as in every scene figure), line style from the kernel:
    ``matrix (numba)`` solid, ``matrix (numpy)`` dashed; other rows (pin.rnea, PyDy) dash-dot."""
    from exo_bench.bench.output.figures.palette import method_color

    bases = sorted({_base(m) for m in methods})
    return {
        "color": method_color(_base(method), bases),
        "ls": {"numba": "-", "numpy": "--", "": "-"}.get(_kernel(method), "-."),
    }
