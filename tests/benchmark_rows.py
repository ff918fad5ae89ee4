"""Rows of a benchmark run's frame, as the report functions read them (bench/perf/reports): the tests of
the reports build their runs from these (tests/test_bench_reports.py, tests/test_peer_ratios.py)."""

from __future__ import annotations


def exo5_3d_row(
    group: str,
    method: str,
    batched: bool,
    samples: int,
    median: float,
    *,
    err: float = 1e-15,
    rel_err: float | None = None,
    threads: int | str = "",
) -> dict:
    """One row of exo5-3d: ``median`` seconds a call of ``samples`` samples; errors ``err`` (absolute) and
    ``rel_err`` (relative; default ``err``) against the reference."""
    return {
        "mechanism": "exo5-3d",
        "n": 5,
        "dim": 3,
        "topology": "exo5",
        "iqr": 0.0,
        "reference": "ref",
        "nonfinite": 0,
        "max_abs_err": err,
        "max_rel_err": err if rel_err is None else rel_err,
        "threads": threads,
        "group": group,
        "method": method,
        "batched": batched,
        "samples": samples,
        "median": median,
    }
