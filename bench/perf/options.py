"""Typed options of the benchmark job (``exo-bench bench``)."""

from __future__ import annotations

from dataclasses import dataclass

from exo_bench.bench.studies.options import ClusterOptions, ReportOptions


@dataclass(frozen=True)
class BenchOptions(ReportOptions):
    """``exo-bench bench``: the benchmark suite and its reports."""

    #: Also replace the paper table in the checkout's README.md.
    update_readme: bool = False
    #: Run the sweep as tasks on a Dask cluster (None: serial in this process).
    cluster: ClusterOptions | None = None
    #: Only the sweep's rows whose key matches one of these shell-style patterns (empty: every row).
    rows: tuple[str, ...] = ()
    #: Seconds the serial benchmark suite may run before it is stopped (None: the profile's predicted
    #: time times an allowance, bench/perf/reports/benchmark_reports.py suite_timeout).
    suite_timeout: float | None = None
