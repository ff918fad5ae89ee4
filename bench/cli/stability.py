"""``exo-bench stability [--full] [--reports DIR] [--workers N | --scheduler ADDRESS]``: where each
method breaks, and the forward-dynamics round trip; stability.md and its plots."""

from __future__ import annotations

import argparse
import dataclasses

from exo_bench.bench.cli.arguments import (
    add_cluster_args,
    add_reports,
    cluster_options,
    report_job,
    reports_folder,
    subcommand,
)
from exo_bench.bench.studies.options import StabilityOptions


def add_parser(sub: argparse._SubParsersAction) -> None:
    s = subcommand(
        sub,
        "stability",
        cmd_stability,
        "where each method breaks (extreme cases vs the 50-digit reference) and the "
        "forward-dynamics round trip; write stability.md and its plots",
        "exo-bench stability --reports my-reports",
        "exo-bench stability --full --workers 2",
    )
    s.add_argument("--full", action="store_true", help="the whole sweep (finer distances, n = 100, more tolerances)")
    add_reports(s)
    add_cluster_args(s)


def cmd_stability(args: argparse.Namespace) -> int:
    from exo_bench.bench.studies.stability.report import run

    opts = StabilityOptions(reports=reports_folder(args.reports), full=args.full, cluster=cluster_options(args))
    if opts.cluster is not None:
        from exo_bench.bench.cluster.commands import stability_evaluator

        opts = dataclasses.replace(opts, evaluate=stability_evaluator(opts))
    return report_job(run, opts, "exo-bench stability")
