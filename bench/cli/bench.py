"""``exo-bench bench [--full] [--update-readme] [--reports DIR] [--workers N | --scheduler ADDRESS]``:
the benchmark suite and its reports (paper_table, error_vs_runtime, scaling, derivatives)."""

from __future__ import annotations

import argparse

from exo_bench.bench.cli.arguments import (
    add_cluster_args,
    add_reports,
    budget_arg,
    cluster_options,
    report_job,
    reports_folder,
    subcommand,
)
from exo_bench.bench.studies.options import BenchOptions


def full_help() -> str:
    """``--full``'s help, from the full sweep's definition (bench/perf/profiles.py FULL): its largest models
    and its samples per batch."""
    from exo_bench.bench.perf import profiles

    full = profiles.FULL
    largest = max((*full.inverse_n, *full.scaling_n, *full.forward_n))
    alone = f", newton-euler alone to {max(full.newton_euler_n):,}" if full.newton_euler_n else ""
    return f"the whole sweep (n up to {largest:,}{alone}, {full.samples:,} samples per batch); slow"


def add_parser(sub: argparse._SubParsersAction) -> None:
    s = subcommand(
        sub,
        "bench",
        cmd_bench,
        "run the benchmark suite and write paper_table, error_vs_runtime, scaling, derivatives",
        "exo-bench bench --reports my-reports",
        "exo-bench bench --full --workers 2",
    )
    s.add_argument("--full", action="store_true", help=full_help())
    s.add_argument(
        "--update-readme",
        action="store_true",
        help="also replace the paper table and issue 23's figures in the checkout's reports/full/highlights.md, which the README links (only then is it changed)",
    )
    add_reports(s)
    s.add_argument(
        "--rows",
        action="append",
        default=None,
        metavar="PATTERN",
        help="run only the sweep's rows whose key matches PATTERN (shell-style, repeatable; e.g. "
        "'*test_forward_dynamics.py:3d-chain-*'); their reports go to REPORTS/selected-rows, never over "
        "a whole sweep's, and their checkpoints are resumed by a later whole sweep",
    )
    s.add_argument(
        "--suite-timeout",
        type=budget_arg,
        default=None,
        metavar="SECONDS",
        help="stop the serial suite after SECONDS (default: the profile's predicted time x 10)",
    )
    add_cluster_args(s)


def options(args: argparse.Namespace) -> BenchOptions:
    rows = tuple(args.rows or ())
    cluster = cluster_options(args)
    if rows and cluster is None:  # a selection of rows runs on the cluster's machinery
        from exo_bench.bench.studies.options import ClusterOptions

        cluster = ClusterOptions(workers=args.workers, scheduler=args.scheduler)
    return BenchOptions(
        reports=reports_folder(args.reports),
        full=args.full,
        update_readme=args.update_readme,
        cluster=cluster,
        rows=rows,
        suite_timeout=args.suite_timeout,
    )


def cmd_bench(args: argparse.Namespace) -> int:
    from exo_bench.bench.perf.reports.benchmark_reports import run

    opts = options(args)
    if opts.cluster is not None:
        from exo_bench.bench.cluster.commands import bench_run as run
    return report_job(run, opts, "exo-bench bench")
