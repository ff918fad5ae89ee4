"""What the subcommands share: argument types (one line on a bad value), the ``--reports`` folder,
the cluster options, and how a report job run on its own marks its files."""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from exo_bench.bench.studies.options import ClusterOptions, ReportOptions

MAX_MEMORY_HELP = (
    "refuse (one line, before any work) a method whose estimated memory exceeds SIZE, e.g. 2G, 512M "
    "(default: 80%% of the machine's available memory); the estimate and a method that fits are named"
)


#: The help of the argument that names a mechanism.
MECHANISM_HELP = "a preset name (exo-bench presets) or a mechanism JSON file"


def subcommand(
    sub: argparse._SubParsersAction,
    name: str,
    func: Callable[[argparse.Namespace], int],
    summary: str,
    *examples: str,
    mechanism: bool | str = False,
) -> argparse.ArgumentParser:
    """Register ``exo-bench name``, which runs ``func(args)``. Its ``--help`` says in one line what it does
    (``summary``, also its line in ``exo-bench --help``) and shows ``examples``, each one ``exo-bench ...``
    command line, kept as written (tests/test_cli_help.py parses each). ``mechanism``: a first argument
    names a mechanism (a string: its ``nargs``, ``"?"`` for an optional one). The subcommand's own
    arguments go on the parser returned."""
    s = sub.add_parser(
        name,
        help=summary,
        description=summary,
        epilog="examples:\n" + "\n".join(f"  {e}" for e in examples),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    s.set_defaults(func=func)
    if mechanism:
        s.add_argument("mechanism", nargs=None if mechanism is True else mechanism, help=MECHANISM_HELP)
    return s


def add_reports(
    s: argparse.ArgumentParser, help: str = "output folder (default: ./reports in the current directory)"
) -> None:
    """``--reports DIR`` (default None: ./reports; read by :func:`reports_folder`)."""
    s.add_argument("--reports", default=None, help=help)


def add_max_memory(s: argparse.ArgumentParser, help: str = MAX_MEMORY_HELP) -> None:
    """``--max-memory SIZE`` (:func:`size_arg`; default None: the usable memory)."""
    s.add_argument("--max-memory", type=size_arg, default=None, metavar="SIZE", help=help)


def reports_folder(value: str | None) -> Path | None:
    """``--reports``: a usable folder (:func:`~exo_bench.bench.output.provenance.writable_folder`)
    whose ``runs.json``, if any, has the shape the publisher reads; checked before any work starts."""
    from exo_bench.bench.output.json_shape import check_manifest_file
    from exo_bench.bench.output.provenance import REPORTS, writable_folder

    if value is not None:
        writable_folder(value, "--reports")
    check_manifest_file(REPORTS if value is None else value)  # its runs.json, read after the work: now
    return None if value is None else Path(value)


O = TypeVar("O", bound=ReportOptions)


def report_job(run: Callable[[O], int], options: O, command: str) -> int:
    """A suite job run on its own: its files are marked with this process's run in the folder's
    runs.json and summary.md (:mod:`exo_bench.bench.output.publish`), so the summary always says
    which run made each file."""
    from exo_bench.bench.output.publish import record_files, snapshot

    out = options.folder
    before = snapshot(out)
    try:
        return run(options)
    finally:
        record_files(out, before, command + (" --full" if options.full else ""))


def cluster_options(args: argparse.Namespace) -> ClusterOptions | None:
    """The full sweep runs on a Dask cluster (:mod:`exo_bench.bench.cluster`); so does the quick one
    when --workers or --scheduler is given. None: serial, in this process."""
    if args.full or args.workers is not None or args.scheduler:
        return ClusterOptions(workers=args.workers, scheduler=args.scheduler)
    return None


#: A decimal literal: ASCII digits, an optional sign, point and exponent; no underscores, no spaces
#: (``float()`` reads "1.4_1" as 1.41, " 2 " as 2 and Arabic-Indic digits).
DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: A whole-number literal: ASCII digits with an optional sign.
WHOLE = re.compile(r"[+-]?[0-9]+")
_FORM = "(ASCII digits, an optional sign, point and exponent; no underscores or spaces)"
_WHOLE_FORM = "(ASCII digits and an optional sign; no underscores or spaces)"


def decimal(text: str) -> float:
    """The one reader of a number option's text (issue 34, W8): a :data:`DECIMAL` literal, else argparse's
    one-line error (argparse names the option)."""
    if not DECIMAL.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected a decimal number such as 1.41, got {text!r} {_FORM}")
    return float(text)


def whole(text: str) -> int:
    """A whole-number option's text: a :data:`WHOLE` literal, else argparse's one-line error."""
    if not WHOLE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected a whole number such as 3, got {text!r} {_WHOLE_FORM}")
    return int(text)


def size_arg(text: str) -> int:
    from exo_bench.api.cost_model import parse_size

    if text != text.strip():  # parse_size strips: an option's text is taken as typed
        raise argparse.ArgumentTypeError(f"expected a size such as 2G, 512M or 1.5e9 (no spaces), got {text!r}")
    try:
        return parse_size(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--max-memory: ")) from None


def seconds_arg(text: str) -> float:
    from exo_bench.api.cost_model import parse_seconds

    decimal(text)  # the strict literal first: parse_seconds' float() reads "1_0" and " 2 "
    try:
        return parse_seconds(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--max-time: ")) from None


def budget_arg(text: str) -> float:
    value = decimal(text)
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def at_least_one(text: str, plural: str, singular: str) -> int:
    """``text`` as a whole number of at least 1, else argparse's error naming ``plural``/``singular``."""
    if not WHOLE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected a whole number of {plural}, got {text!r} {_WHOLE_FORM}")
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected at least 1 {singular}, got {value}")
    return value


def workers_arg(text: str) -> int:
    value = at_least_one(text, "worker processes", "worker")
    from exo_bench.models.machine.memory import count_problem

    problem = count_problem(value, "worker processes")  # the bound of every count (issue 34, L3)
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return value


def add_cluster_args(s: argparse.ArgumentParser) -> None:
    s.add_argument(
        "--workers",
        type=workers_arg,
        default=None,
        metavar="N",
        help="run the sweep on a local Dask cluster of N single-threaded worker processes (default: one "
        "per core; 1 = serial)",
    )
    s.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run the sweep on the running Dask cluster at ADDRESS (e.g. tcp://10.0.0.1:8786)",
    )
