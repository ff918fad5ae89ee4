"""The size study of the equations: ``exo-bench equations --size-report [--full]`` ->
``reports/equations_size.md`` and ``equations_size.png``.

For chains and random trees of n = 1..20 (quick: 1..4) in 2D and 3D: the operation count after
CSE, the lines of generated C and the seconds to compose and to generate, for the matrix method,
our Lagrange II derivation and sympy's ``LagrangesMethod`` (each within a budget).
"""

from __future__ import annotations

import sys
import time
from typing import TypedDict

from exo_bench.bench.output.publish import EQUATIONS_SIZE
from exo_bench.bench.studies.options import ReportOptions


# ------------------------------------------------------------------------------ the size study
QUICK_N = (1, 2, 3, 4)
FULL_N = tuple(range(1, 21))
ROUTES = ("matrix", "lagrange", "LagrangesMethod")
QUICK_BUDGET, FULL_BUDGET = 10.0, 30.0
#: The matrix method's points get this many times the budget: the study's subject must reach n = 20.
MATRIX_BUDGET_FACTOR = 6


class SizePoint(TypedDict):
    """One measurement of :func:`size_point`."""

    compose: float  # seconds composing tau (and, for the matrix method, its matrices)
    generate: float  # seconds of CSE, counting and C printing
    ops: int  # sympy.count_ops of tau after CSE
    c_lines: int  # lines of the generated header and source


def size_point(mech, route: str, budget: float) -> SizePoint:
    """One measurement: compose seconds, generate seconds (CSE and C printing), operations after
    CSE of tau (``sympy.count_ops``) and lines of generated C (header and source); the whole point
    within ``budget`` seconds (``lagrange.budget.time_budget``) or BudgetExceeded."""

    from exo_bench.lagrange.budget import time_budget

    with time_budget(budget, f"composing and generating the equations ({route})", mech.nlinks, mech.dim):
        return _size_point(mech, route, budget)


def _size_point(mech, route: str, budget: float) -> SizePoint:
    import sympy as sp

    from exo_bench.matrix_method.export import code as export_code
    from exo_bench.models.mechanism.symbols import symbols_for

    S = symbols_for(mech.nlinks, mech.dim)
    t0 = time.perf_counter()
    if route == "matrix":
        from exo_bench.matrix_method.symbolic import clear_caches

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


def size_report(options: ReportOptions) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from exo_bench.bench.output.provenance import provenance, save_figure
    from exo_bench.models.files import atomic_write
    from exo_bench.models.mechanism.presets import chain, random_tree

    full = options.full
    out = options.folder
    ns = FULL_N if full else QUICK_N
    budget = FULL_BUDGET if full else QUICK_BUDGET
    rows: list[tuple[int, str, int, str, SizePoint | None, str]] = []
    over: dict[tuple[int, str, str], str] = {}
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
                    print(
                        f"size: {dim}D {kind} n={n} {route}: {rows[-1][4] or rows[-1][5]}", file=sys.stderr, flush=True
                    )
    cmd = "exo-bench equations --size-report" + (" --full" if full else "")
    lines = [
        "# The size of the equations: the matrix method against Lagrange",
        "",
        provenance(cmd),
        "",
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
        "(indicative; ratios within one run).",
        "",
    ]
    ratio_lines: list[tuple[int, str, int, float, float | None, float]] = []
    for dim in (2, 3):
        for kind in ("chain", "tree"):
            for n in ns:
                got = {r[3]: r[4] for r in rows if r[:3] == (dim, kind, n) and r[4]}
                if "matrix" in got and "lagrange" in got:
                    ratio_lines.append(
                        (
                            dim,
                            kind,
                            n,
                            got["lagrange"]["ops"] / got["matrix"]["ops"],
                            got["LagrangesMethod"]["ops"] / got["matrix"]["ops"] if "LagrangesMethod" in got else None,
                            got["lagrange"]["compose"] / max(got["matrix"]["compose"], 1e-9),
                        )
                    )
    if ratio_lines:
        lines += [
            "## The answer, per model: Lagrange's size over the matrix method's",
            "",
            "| dim | kind | n | ops: lagrange / matrix | ops: LagrangesMethod / matrix | compose s: lagrange / matrix |",
            "|---|---|---|---|---|---|",
        ]
        for dim, kind, n, r1, r2, r3 in ratio_lines:
            lines.append(f"| {dim}D | {kind} | {n} | {r1:.2f} | {'' if r2 is None else f'{r2:.2f}'} | {r3:.1f} |")
        lines.append("")
    lines += [
        "## Every measurement",
        "",
        "| dim | kind | n | route | ops after CSE | C lines | compose s | generate s | note |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for dim, kind, n, route, point, note in rows:
        if point:
            lines.append(
                f"| {dim}D | {kind} | {n} | {route} | {point['ops']} | {point['c_lines']} | {point['compose']:.3g} | "
                f"{point['generate']:.3g} | {note} |"
            )
        else:
            lines.append(f"| {dim}D | {kind} | {n} | {route} | | | | | not run: {note.replace('|', '/')} |")
    from exo_bench.bench.output.files import announce_narrower, narrower_names

    names = narrower_names(out, EQUATIONS_SIZE, full)  # never over a --full run's
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
