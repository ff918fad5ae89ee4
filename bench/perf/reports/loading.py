"""The benchmark JSON as pandas frames: rows, skips and the machine; a row name's method and kernel."""

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
