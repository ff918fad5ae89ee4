"""``exo-bench equations``: the equations of a mechanism taken away as LaTeX, Python or C; the
``equations`` output of a scene; and the size study ``reports/equations_size.md``.

* ``exo-bench equations MECHANISM --format latex|python|c|casadi [-o DIR] [--symbolic-parameters]``
  writes ``equations-<name>.md`` and ``.tex`` (latex), ``<name>.py`` (python), ``<name>.h`` and
  ``<name>.c`` (c) or ``<name>_<function>.casadi`` and ``<name>_casadi.md`` (casadi: the
  ``casadi.Function`` files of :mod:`matrix_method.export_casadi`, the optional extra ``casadi``)
  into ``DIR`` (default: the current folder), atomically (a failure leaves no file
  of the set half-written). The work is estimated first (:func:`bench.resources.equations_estimate`)
  and refused in one line when it exceeds ``--budget`` (seconds, default :data:`DEFAULT_BUDGET`);
  the same budget is checked again between the phases.
* A scene listing ``equations`` in its outputs gets ``equations-<scene>.md`` and ``.tex`` in the
  reports (:func:`bench.equation_pages.scene_pages`); a two-link planar scene's page writes eq. (4) with both signs.
* ``exo-bench equations --size-report [--full]`` measures, for chains and random trees of
  n = 1..20 (quick: 1..4) in 2D and 3D, the operation count after CSE, the lines of generated C and
  the seconds to compose and to generate, for the matrix method, our Lagrange II derivation and
  sympy's ``LagrangesMethod`` (each within a budget), and writes ``equations_size.md`` and
  ``equations_size.png``.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from exo_bench.bench.equation_pages import (DEFAULT_BUDGET, EquationsBudget, _Clock, eq4_pair,  # noqa: F401
                                            md_matrices, scene_pages)

FORMATS = ("latex", "python", "c", "casadi")


# ------------------------------------------------------------------------------ the command
def add_parser(sub) -> None:
    """Register ``exo-bench equations`` on the CLI's subparsers."""
    s = sub.add_parser("equations", help="write a mechanism's equations of motion as LaTeX, a standalone Python "
                       "module or C99 source (eq. (5)/(17) composed by the matrix method)")
    s.add_argument("mechanism", nargs="?", help="a preset name or a mechanism JSON file")
    s.add_argument("--format", choices=None, default=None, metavar="FORMAT",
                   help="latex (a Markdown page and a standalone .tex), python (imports numpy only), c (C99 "
                        ".h and .c) or casadi (casadi.Function files .casadi and a note; the extra 'casadi')")
    s.add_argument("-o", "--output", default=".", metavar="DIR", help="output folder (default: the current folder)")
    s.add_argument("--symbolic-parameters", action="store_true",
                   help="keep masses, fractions and g as symbols (latex: the aggregates of eq. (6); python and c: "
                        "one more input, params)")
    s.add_argument("--budget", type=_budget_arg, default=DEFAULT_BUDGET, metavar="SECONDS",
                   help=f"seconds that composing and generating may take (default {DEFAULT_BUDGET:g}); estimated "
                        "before any work")
    s.add_argument("--size-report", action="store_true",
                   help="instead: measure the size of the equations (matrix method vs Lagrange) for chains and "
                        "trees and write equations_size.md into --reports")
    s.add_argument("--full", action="store_true", help="with --size-report: n = 1..20 (default 1..4)")
    s.add_argument("--reports", default=None, help="with --size-report: output folder (default: ./reports)")
    s.set_defaults(func=cmd_equations)


def cmd_equations(args) -> int:
    from exo_bench.models.loading import load_mechanism

    if args.size_report:
        from exo_bench.bench.reporting import REPORTS
        from exo_bench.bench.runner import record_files, snapshot

        if args.mechanism is not None or args.format is not None:
            raise ValueError("equations --size-report: takes no MECHANISM and no --format")
        if args.reports is not None:
            output_folder(args.reports, "--reports")
        out = Path(args.reports) if args.reports else REPORTS
        before = snapshot(out)
        try:
            return size_report(args)
        finally:
            record_files(out, before, "exo-bench equations --size-report" + (" --full" if args.full else ""))
    if args.format not in FORMATS:
        got = "nothing" if args.format is None else repr(args.format)
        raise ValueError(f"equations --format: expected one of {', '.join(FORMATS)}, got {got}")
    if args.mechanism is None:
        raise ValueError("equations: expected a MECHANISM (a preset name or a JSON file)")
    out = output_folder(args.output)
    mech = load_mechanism(args.mechanism)
    for p in write_equations(mech, args.format, out, args.symbolic_parameters, args.budget):
        print(f"wrote {p}")
    return 0


def _budget_arg(text: str) -> float:
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def output_folder(value, option: str = "-o") -> Path:
    """``-o`` (or ``--reports``) of ``exo-bench equations``: :func:`reporting.writable_folder`."""
    from exo_bench.bench.reporting import writable_folder

    return writable_folder(value, f"equations {option}")


def file_stem(name: str) -> str:
    import re

    return re.sub(r"[^0-9A-Za-z._-]", "_", name) or "mechanism"


def render(mech, fmt: str, symbolic_parameters: bool = False, budget: float = DEFAULT_BUDGET) -> dict[str, str]:
    """``file name -> text`` of the equations of ``mech`` in ``fmt`` (nothing written)."""
    import exo_bench
    from exo_bench.matrix_method import export_code, export_latex

    clock = _Clock(mech, fmt, budget)
    stem = file_stem(mech.name)
    if fmt == "latex":
        parts = export_latex.element_parts(mech, symbolic_parameters)
        clock.check("composing")
        header = _latex_header(mech, symbolic_parameters)
        md = export_latex.document(mech, symbolic_parameters, "md", header, parts=parts, eq4=eq4_pair(mech),
                                   matrices_shown=md_matrices(mech))
        clock.check("the Markdown page")
        tex = export_latex.document(mech, symbolic_parameters, "tex", "", parts=parts, eq4=eq4_pair(mech))
        clock.check("the LaTeX file")
        return {f"equations-{stem}.md": md, f"equations-{stem}.tex": tex}
    if fmt == "casadi":
        return _casadi_files(mech, stem, symbolic_parameters, clock)
    es = export_code.equation_set(mech, symbolic_parameters)
    clock.check("composing")
    if fmt == "python":
        text = export_code.python_module(es, exo_bench.__version__)
        clock.check("generating Python")
        return {f"{export_code.c_identifier(mech.name)}.py": text}
    prefix, h, c = export_code.c_sources(es, exo_bench.__version__)
    clock.check("generating C")
    return {f"{prefix}.h": h, f"{prefix}.c": c}


def write_equations(mech, fmt: str, out: Path, symbolic_parameters: bool = False,
                    budget: float = DEFAULT_BUDGET) -> list[Path]:
    """Render, then write every file atomically (all are rendered before the first is written)."""
    from contextlib import ExitStack

    from exo_bench.bench.reporting import atomic_path

    files = render(mech, fmt, symbolic_parameters, budget)
    out = Path(out)
    paths = []
    with ExitStack() as stack:  # every file renamed into place only when all were written
        for name, text in files.items():
            tmp = stack.enter_context(atomic_path(out / name))
            tmp.write_text(text)
            paths.append(out / name)
    return paths


def _casadi_files(mech, stem: str, symbolic_parameters: bool, clock) -> dict[str, str]:
    """``--format casadi``: ``<stem>_<function>.casadi`` files and the note ``<stem>_casadi.md``; with
    ``--symbolic-parameters`` every function takes the masses, fractions and g as ``params``."""
    import exo_bench
    from exo_bench.bench.reporting import provenance
    from exo_bench.matrix_method import export_casadi

    export_casadi.require_casadi()
    flag = " --symbolic-parameters" if symbolic_parameters else ""
    files = export_casadi.export_files(mech, stem, exo_bench.__version__,
                                       provenance(f"exo-bench equations {mech.name} --format casadi{flag}"),
                                       symbolic_parameters)
    clock.check("building and serialising the CasADi functions")
    return files


def _latex_header(mech, symbolic_parameters: bool) -> str:
    from exo_bench.bench.reporting import provenance

    flag = " --symbolic-parameters" if symbolic_parameters else ""
    return provenance(f"exo-bench equations {mech.name} --format latex{flag}")


# ------------------------------------------------------------------------------ the size study
QUICK_N = (1, 2, 3, 4)
FULL_N = tuple(range(1, 21))
ROUTES = ("matrix", "lagrange", "LagrangesMethod")
QUICK_BUDGET, FULL_BUDGET = 10.0, 30.0
#: The matrix method's points get this many times the budget: the study's subject must reach n = 20.
MATRIX_BUDGET_FACTOR = 6


def size_point(mech, route: str, budget: float) -> dict:
    """One measurement: compose seconds, generate seconds (CSE and C printing), operations after
    CSE of tau (``sympy.count_ops``) and lines of generated C (header and source); the whole point
    within ``budget`` seconds (``lagrange.budget.time_budget``) or BudgetExceeded."""

    from exo_bench.lagrange.budget import time_budget

    with time_budget(budget, f"composing and generating the equations ({route})", mech.nlinks, mech.dim):
        return _size_point(mech, route, budget)


def _size_point(mech, route: str, budget: float) -> dict:
    import sympy as sp

    from exo_bench.matrix_method import export_code
    from exo_bench.models.symbols import symbols_for

    S = symbols_for(mech.nlinks, mech.dim)
    t0 = time.perf_counter()
    if route == "matrix":
        from exo_bench.matrix_method.polynomials import clear_caches

        clear_caches()
        t0 = time.perf_counter()
        es = export_code.equation_set(mech)
    else:
        from exo_bench.lagrange.derivation import derive
        from exo_bench.lagrange.peer import peer_equations

        if route == "lagrange":
            d = derive(mech, budget=budget, cache=False)
            tau = list(d.equations)
        else:
            tau = list(peer_equations(mech, "lagrange", symbolic_parameters=False, budget=budget))
        M = sp.Matrix(tau).jacobian(list(S.qdd))
        zero = {s: sp.S.Zero for s in S.qdd}
        es = export_code.EquationSet(mech, S, False, tau, M.tolist(), [e.xreplace(zero) for e in tau])
    compose = time.perf_counter() - t0
    t1 = time.perf_counter()
    ops = export_code.operation_count(es.tau)
    _, h, c = export_code.c_sources(es, "size-study")
    generate = time.perf_counter() - t1
    return {"compose": compose, "generate": generate, "ops": ops, "c_lines": len(h.splitlines()) + len(c.splitlines())}


def size_report(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from exo_bench.bench.reporting import REPORTS, atomic_write, provenance, save_figure
    from exo_bench.models.presets import chain, random_tree

    full = bool(getattr(args, "full", False))
    out = Path(args.reports) if getattr(args, "reports", None) else REPORTS
    ns = FULL_N if full else QUICK_N
    budget = FULL_BUDGET if full else QUICK_BUDGET
    rows, over = [], {}
    for dim in (2, 3):
        for kind in ("chain", "tree"):
            for n in ns:
                mech = chain(n, dim) if kind == "chain" else random_tree(n, dim, seed=n)
                for route in ROUTES:
                    key = (dim, kind, route)
                    if key in over:
                        rows.append((dim, kind, n, route, None, over[key]))
                        continue
                    try:
                        r = size_point(mech, route, budget * (MATRIX_BUDGET_FACTOR if route == "matrix" else 1))
                        rows.append((dim, kind, n, route, r, ""))
                    except Exception as e:  # noqa: BLE001 - a budget: the larger n are skipped too
                        reason = getattr(e, "skip_reason", None) or f"{type(e).__name__}: {e}"
                        over[key] = f"over the budget of {budget:g} s at n = {n}"
                        rows.append((dim, kind, n, route, None, reason.splitlines()[0]))
                    print(f"size: {dim}D {kind} n={n} {route}: {rows[-1][4] or rows[-1][5]}", file=sys.stderr,
                          flush=True)
    cmd = "exo-bench equations --size-report" + (" --full" if full else "")
    lines = ["# The size of the equations: the matrix method against Lagrange", "", provenance(cmd), "",
             "Are the paper's matrices a more compact form of the same equations, and by how much? For chains "
             f"(`presets.chain`) and seeded random trees (`presets.random_tree(n, dim, seed=n)`) of n = {ns[0]}..{ns[-1]} "
             "links, the inverse dynamics tau composed three ways: the matrix method (eq. (5)/(17), "
             "`matrix_method.symbolic.compose_equations`), our Lagrange II derivation (`lagrange.derive`) and "
             "sympy's `LagrangesMethod` (`lagrange.peer`), each with the mechanism's numbers. `ops`: "
             "`sympy.count_ops` of tau after `sympy.cse` (temporaries and outputs); `C lines`: the header and "
             "source `exo-bench equations --format c` writes for the three functions (tau, M, h) from that route's "
             "tau; `compose s`: composing tau (and, for the matrix method, the matrices); `generate s`: CSE, "
             "counting and C printing. The three routes give the same equations (tests/test_equations_export.py "
             "and tests/test_symbolic.py check it); only their form differs. A route over its budget "
             f"({budget:g} s per point for Lagrange's routes, {budget * MATRIX_BUDGET_FACTOR:g} s for the matrix "
             "method's) is not run for larger n. Times are one run on a shared machine "
             "(indicative; ratios within one run).", ""]
    ratio_lines = []
    for dim in (2, 3):
        for kind in ("chain", "tree"):
            for n in ns:
                got = {r[3]: r[4] for r in rows if r[:3] == (dim, kind, n) and r[4]}
                if "matrix" in got and "lagrange" in got:
                    ratio_lines.append((dim, kind, n, got["lagrange"]["ops"] / got["matrix"]["ops"],
                                        got["LagrangesMethod"]["ops"] / got["matrix"]["ops"]
                                        if "LagrangesMethod" in got else None,
                                        got["lagrange"]["compose"] / max(got["matrix"]["compose"], 1e-9)))
    if ratio_lines:
        lines += ["## The answer, per model: Lagrange's size over the matrix method's", "",
                  "| dim | kind | n | ops: lagrange / matrix | ops: LagrangesMethod / matrix | compose s: lagrange / matrix |",
                  "|---|---|---|---|---|---|"]
        for dim, kind, n, r1, r2, r3 in ratio_lines:
            lines.append(f"| {dim}D | {kind} | {n} | {r1:.2f} | {'' if r2 is None else f'{r2:.2f}'} | {r3:.1f} |")
        lines.append("")
    lines += ["## Every measurement", "", "| dim | kind | n | route | ops after CSE | C lines | compose s | generate s | note |",
              "|---|---|---|---|---|---|---|---|---|"]
    for dim, kind, n, route, r, note in rows:
        if r:
            lines.append(f"| {dim}D | {kind} | {n} | {route} | {r['ops']} | {r['c_lines']} | {r['compose']:.3g} | "
                         f"{r['generate']:.3g} | {note} |")
        else:
            lines.append(f"| {dim}D | {kind} | {n} | {route} | | | | | not run: {note.replace('|', '/')} |")
    from exo_bench.bench.output_files import announce_narrower, narrower_names
    names = narrower_names(out, ["equations_size.md", "equations_size.png"], full)   # never over a --full run's
    announce_narrower(out, names, "equation size reports")
    lines += ["", f"![operations after CSE against n, log-log]({names['equations_size.png']})", ""]
    out.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), sharey=True)
    styles = {"matrix": "-o", "lagrange": "--s", "LagrangesMethod": ":^"}
    for ax, dim in zip(axes, (2, 3)):
        for kind, color in (("chain", "C0"), ("tree", "C1")):
            for route in ROUTES:
                pts = [(n, r["ops"]) for d, k, n, rt, r, _ in rows if (d, k, rt) == (dim, kind, route) and r]
                if pts:
                    ax.loglog(*zip(*pts), styles[route], color=color, label=f"{route}, {kind}", markersize=4)
        ax.set_title(f"{dim}D: sympy.count_ops of tau after CSE")
        ax.set_xlabel("links n")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("operations")
    axes[1].legend(fontsize=7)
    fig.tight_layout()
    png = save_figure(fig, out / names["equations_size.png"])
    plt.close(fig)
    md = atomic_write(out / names["equations_size.md"], "\n".join(lines))
    print(f"wrote {md}\nwrote {png}")
    return 0
