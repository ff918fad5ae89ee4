"""``exo-bench errata [--reports DIR]``: every printed formula of the paper against Lagrange and
Pinocchio; errata.md."""

from __future__ import annotations

import argparse

from exo_bench.bench.cli.arguments import add_reports, report_job, reports_folder, subcommand
from exo_bench.bench.studies.options import ReportOptions


def add_parser(sub: argparse._SubParsersAction) -> None:
    s = subcommand(
        sub,
        "errata",
        cmd_errata,
        "check every printed formula of the paper against Lagrange and Pinocchio; write errata.md",
        "exo-bench errata --reports my-reports",
    )
    add_reports(s)


def cmd_errata(args: argparse.Namespace) -> int:
    from exo_bench.bench.studies.errata import run

    return report_job(run, ReportOptions(reports=reports_folder(args.reports)), "exo-bench errata")
