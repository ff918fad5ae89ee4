"""Typed options of the studies and report jobs, the benchmark job (``exo-bench bench``) among them. The
command line (:mod:`exo_bench.bench.cli`) is the only user of argparse: it builds these from its arguments; code and tests build them directly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from exo_bench.bench.output.provenance import REPORTS


@dataclass(frozen=True)
class ReportOptions:
    """A job that writes reports (errata, stability, benchmarks, the equations' size study)."""

    #: Output folder (None: ``./reports`` of the current directory).
    reports: Path | None = None
    #: The whole sweep instead of the quick profile.
    full: bool = False
    #: The folder the files are published to when ``reports`` is a staging folder (the main job).
    published_to: Path | None = None

    @property
    def folder(self) -> Path:
        """The folder the job writes into."""
        return Path(self.reports) if self.reports is not None else REPORTS


@dataclass(frozen=True)
class ClusterOptions:
    """Where a sweep's tasks run: a local Dask cluster of ``workers`` processes, or the running
    cluster at ``scheduler`` (None and None: the default local cluster, or serial when not on a cluster)."""

    workers: int | None = None
    scheduler: str | None = None
    #: seconds the parts may all run without one finishing (bench/cluster/waits.py PART_SILENCE)
    wait_timeout: float = 3 * 3600.0  # equal to PART_SILENCE (options sit below cluster in the layers)


#: ``evaluate(profile, methods, log) -> (families, forward)``: computes the stability study's results
#: elsewhere (on a Dask cluster); None: this process does.
Evaluator = Callable[[Any, list[str], Callable[[str], None]], tuple[Any, Any]]


@dataclass(frozen=True)
class StabilityOptions(ReportOptions):
    """``exo-bench stability``."""

    cluster: ClusterOptions | None = None
    evaluate: Evaluator | None = None


@dataclass(frozen=True)
class RunOptions:
    """``exo-bench run``: the main job."""

    #: Shipped scene names or scene TOML files (empty: every shipped scene, then the suite's reports).
    scenes: tuple[str, ...] = ()
    reports: Path | None = None
    full: bool = False
    #: Bytes a scene's method may take (None: the default share of the available memory).
    max_memory: int | None = None

    @property
    def folder(self) -> Path:
        return Path(self.reports) if self.reports is not None else REPORTS


# Typed options of the benchmark job (``exo-bench bench``).


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
