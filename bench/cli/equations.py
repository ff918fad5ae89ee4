"""``exo-bench equations``: the equations of a mechanism taken away as LaTeX, Python or C; the
``equations`` output of a scene; and the size study ``reports/equations_size.md``
(:mod:`exo_bench.bench.studies.equations_size`).

* ``exo-bench equations MECHANISM --format latex|python|c|casadi [-o DIR] [--symbolic-parameters]``
  writes ``equations-<name>.md`` and ``.tex`` (latex), ``<name>.py`` (python), ``<name>.h`` and
  ``<name>.c`` (c) or ``<name>_<function>.casadi`` and ``<name>_casadi.md`` (casadi: the
  ``casadi.Function`` files of :mod:`exo_bench.matrix_method.export.casadi_functions`, the optional
  extra ``casadi``; ``<name>``: the file stem of the mechanism's name, :func:`exo_bench.models.files.file_stem`;
  the Python module and the C prefix never take a standard module's or header's name,
  :mod:`exo_bench.models.files`) into ``DIR`` (default: the current folder), atomically (a failure leaves no file
  of the set half-written). The work is estimated first (:func:`exo_bench.api.cost_model.equations_estimate`)
  and refused in one line when it exceeds ``--budget`` (seconds, default :data:`DEFAULT_BUDGET`);
  the same budget is checked again between the phases.
* A scene listing ``equations`` in its outputs gets ``equations-<scene>.md`` and ``.tex`` in the
  reports (:func:`exo_bench.bench.output.equation_pages.scene_pages`); a two-link planar scene's page writes eq. (4) with both signs.
* ``exo-bench equations --size-report [--full]`` measures, for chains and random trees of
  n = 1..20 (quick: 1..4) in 2D and 3D, the operation count after CSE, the lines of generated C and
  the seconds to compose and to generate, for the matrix method, our Lagrange II derivation and
  sympy's ``LagrangesMethod`` (each within a budget), and writes ``equations_size.md`` and
  ``equations_size.png``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from exo_bench.bench.cli.arguments import add_reports, budget_arg, report_job, subcommand
from exo_bench.models.files import file_stem
from exo_bench.bench.studies.options import ReportOptions

from exo_bench.bench.output.equation_pages import (
    DEFAULT_BUDGET,  # noqa: F401
    EquationsBudget,  # noqa: F401
    _Clock,  # noqa: F401
    eq4_pair,  # noqa: F401
    md_matrices,  # noqa: F401
    scene_pages,  # noqa: F401
)

FORMATS = ("latex", "python", "c", "casadi")


# ------------------------------------------------------------------------------ the command
def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``exo-bench equations`` on the CLI's subparsers."""
    s = subcommand(
        sub,
        "equations",
        cmd_equations,
        "write a mechanism's equations of motion as LaTeX, a standalone Python module or C99 source "
        "(eq. (5)/(17) composed by the matrix method)",
        "exo-bench equations fig2a-2d --format latex -o equations",
        "exo-bench equations exo5-3d --format c -o generated",
        mechanism="?",
    )
    s.add_argument(
        "--format",
        choices=None,
        default=None,
        metavar="FORMAT",
        help="latex (a Markdown page and a standalone .tex), python (imports numpy only), c (C99 "
        ".h and .c) or casadi (casadi.Function files .casadi and a note; the extra 'casadi')",
    )
    s.add_argument("-o", "--output", default=".", metavar="DIR", help="output folder (default: the current folder)")
    s.add_argument(
        "--symbolic-parameters",
        action="store_true",
        help="keep masses, fractions and g as symbols (latex: the aggregates of eq. (6); python and c: "
        "one more input, params)",
    )
    s.add_argument(
        "--budget",
        type=budget_arg,
        default=DEFAULT_BUDGET,
        metavar="SECONDS",
        help=f"seconds that composing and generating may take (default {DEFAULT_BUDGET:g}); estimated before any work",
    )
    s.add_argument(
        "--size-report",
        action="store_true",
        help="instead: measure the size of the equations (matrix method vs Lagrange) for chains and "
        "trees and write equations_size.md into --reports",
    )
    s.add_argument("--full", action="store_true", help="with --size-report: n = 1..20 (default 1..4)")
    add_reports(s, "with --size-report: output folder (default: ./reports)")


def cmd_equations(args: argparse.Namespace) -> int:
    from exo_bench.models.mechanism.presets import load_mechanism

    if args.size_report:
        from exo_bench.bench.studies.equations_size import size_report

        if args.mechanism is not None or args.format is not None:
            raise ValueError("equations --size-report: takes no MECHANISM and no --format")
        reports = None if args.reports is None else output_folder(args.reports, "--reports")
        return report_job(
            size_report, ReportOptions(reports=reports, full=args.full), "exo-bench equations --size-report"
        )
    if args.format not in FORMATS:
        got = "nothing" if args.format is None else repr(args.format)
        raise ValueError(f"equations --format: expected one of {', '.join(FORMATS)}, got {got}")
    if args.mechanism is None:
        raise ValueError("equations: expected a MECHANISM (a preset name or a JSON file)")
    out = output_folder(args.output)
    mech = load_mechanism(args.mechanism)
    for p in write_equations(mech, args.format, out, args.symbolic_parameters, args.budget, [args.mechanism]):
        print(f"wrote {p}")
    return 0


def output_folder(value, option: str = "-o") -> Path:
    """``-o`` (or ``--reports``) of ``exo-bench equations``: :func:`exo_bench.bench.output.provenance.writable_folder`."""
    from exo_bench.bench.output.json_shape import check_manifest_file
    from exo_bench.bench.output.provenance import writable_folder

    folder = writable_folder(value, f"equations {option}")
    if option == "--reports":
        check_manifest_file(folder)  # its runs.json is read after the work: checked now
    return folder


def render(mech, fmt: str, symbolic_parameters: bool = False, budget: float = DEFAULT_BUDGET) -> dict[str, str]:
    """``file name -> text`` of the equations of ``mech`` in ``fmt`` (nothing written)."""
    import exo_bench
    from exo_bench.matrix_method.export import code as export_code, latex as export_latex
    from exo_bench.bench.output import latex_document

    clock = _Clock(mech, fmt, budget)
    stem = file_stem(mech.name)  # models/files.py: the one file-name encoder
    if fmt == "latex":
        parts = export_latex.element_parts(mech, symbolic_parameters)
        clock.check("composing")
        header = _latex_header(mech, symbolic_parameters)
        md = latex_document.document(
            mech, symbolic_parameters, "md", header, parts=parts, eq4=eq4_pair(mech), matrices_shown=md_matrices(mech)
        )
        clock.check("the Markdown page")
        tex = latex_document.document(mech, symbolic_parameters, "tex", "", parts=parts, eq4=eq4_pair(mech))
        clock.check("the LaTeX file")
        return {f"equations-{stem}.md": md, f"equations-{stem}.tex": tex}
    if fmt == "casadi":
        return _casadi_files(mech, stem, symbolic_parameters, clock)
    es = export_code.equation_set(mech, symbolic_parameters)
    clock.check("composing")
    if fmt == "python":
        text = export_code.python_module(es, exo_bench.__version__)
        clock.check("generating Python")
        return {f"{export_code.module_name(es)}.py": text}  # never numpy.py, math.py...
    prefix, h, c = export_code.c_sources(es, exo_bench.__version__)
    clock.check("generating C")
    return {f"{prefix}.h": h, f"{prefix}.c": c}


def write_equations(
    mech,
    fmt: str,
    out: Path,
    symbolic_parameters: bool = False,
    budget: float = DEFAULT_BUDGET,
    inputs: list[str] | tuple = (),
) -> list[Path]:
    """Render, then write every file atomically (all are rendered before the first is written) by
    the one writer (bench/output/files.py: never through a link, never over one of ``inputs``)."""
    from contextlib import ExitStack

    from exo_bench.bench.output.files import replace_atomically, write_all

    files = render(mech, fmt, symbolic_parameters, budget)
    out = Path(out)
    paths = []
    with ExitStack() as stack:  # every file renamed into place only when all were written
        for name, text in files.items():
            _, fd = stack.enter_context(replace_atomically(out / name, inputs=inputs))
            write_all(fd, text)
            paths.append(out / name)
    return paths


def _casadi_files(mech, stem: str, symbolic_parameters: bool, clock) -> dict[str, str]:
    """``--format casadi``: ``<stem>_<function>.casadi`` files and the note ``<stem>_casadi.md``; with
    ``--symbolic-parameters`` every function takes the masses, fractions and g as ``params``."""
    import exo_bench
    from exo_bench.bench.output.provenance import provenance
    from exo_bench.matrix_method.export import casadi_functions as export_casadi

    export_casadi.require_casadi()
    flag = " --symbolic-parameters" if symbolic_parameters else ""
    files = export_casadi.export_files(
        mech,
        stem,
        exo_bench.__version__,
        provenance(f"exo-bench equations {shell_word(mech.name)} --format casadi{flag}"),
        symbolic_parameters,
    )
    clock.check("building and serialising the CasADi functions")
    return files


def _latex_header(mech, symbolic_parameters: bool) -> str:
    from exo_bench.bench.output.provenance import provenance

    flag = " --symbolic-parameters" if symbolic_parameters else ""
    return provenance(f"exo-bench equations {shell_word(mech.name)} --format latex{flag}")


def shell_word(name: str) -> str:
    """``name`` as one word of the command line shown in the pages' provenance (shell quoting)."""
    import shlex

    return shlex.quote(name)
