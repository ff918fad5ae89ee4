"""Errata study, the report: ``reports/errata.md`` and the ``exo-bench errata`` job."""

from __future__ import annotations


from exo_bench.bench.studies.options import ReportOptions
from exo_bench.bench.studies.errata import cases
from exo_bench.bench.studies.errata.evaluation import TOLERANCE, Results, Verdict, compute
from exo_bench.bench.output import provenance as reporting
from exo_bench.bench.output.provenance import atomic_write, provenance, sci
from exo_bench.bench.output.suite_reports import ERRATA
from exo_bench.matrix_method import printed


def _fmt(x: float) -> str:
    return sci(x) or "—"


def _witness_summary(v: Verdict) -> str:
    parts = []
    for w in ("lagrange", "pinocchio"):
        cs = [c for c in v.checks if c.witness == w]
        done = [c for c in cs if not c.skipped]
        if done:
            parts.append(f"{w} {_fmt(max(c.relative for c in done))}")
        if len(done) < len(cs):
            parts.append(f"{w}: {len(cs) - len(done)} model(s) skipped")
    return "; ".join(parts)


def _models(v: Verdict) -> str:
    names = []
    for c in v.checks:
        if c.model not in names:
            names.append(c.model)
    return ", ".join(names)


def render(r: Results) -> str:
    verdicts, branch, singular, gait_, residual, seconds = (
        r.verdicts,
        r.branch,
        r.singular,
        r.gait,
        r.residual,
        r.seconds,
    )
    L = ["# Errata of Borisov & Chigarev, by computation", "", provenance("exo-bench errata")]
    checked = [v for v in verdicts if v.status != "not checkable"]
    fails = [v for v in checked if v.status != "holds"]
    L += [
        "## Method",
        "",
        "Every formula below is encoded once, exactly as printed in the Russian original "
        "(`matrix_method/printed.py`), and evaluated on seeded random states "
        f"({cases.SAMPLES} per model, seed {cases.SEED}) of the models it speaks about. It is compared with two "
        "independent witnesses: **Lagrange** (`lagrange.derive`, sympy, from the point masses' "
        "T and Pi; matrices and equations lambdified) and **Pinocchio** (CRBA/RNEA on the generated URDF; "
        "every matrix of eq. (5)/(17) read off the mass matrix and the bias forces, "
        "`bench.errata.witnesses.pinocchio_matrices`). A formula **holds** when its largest error, "
        "relative to the largest magnitude of the witness's value on that model, is at most "
        f"{TOLERANCE:g} for both witnesses on every model; otherwise it **fails**.",
        "",
        f"- Models for eq. (18): {', '.join(m.name for m in cases.spatial_models())} (random trees: random "
        "parents including several roots, random signs); each compared with the planar model of the "
        "same structure.",
        f"- Chains for eqs. (6), (22), (25), (26): seeded random chains of {min(cases.CHAIN_LENGTHS)}.."
        f"{max(cases.CHAIN_LENGTHS) + 1} links, each the first links of the next.",
        f"- Pinocchio has exactly the paper's matrix form (only products of a link's own rates): "
        f"eq. (17) rebuilt from the extracted matrices reproduces its inverse dynamics to {_fmt(residual)} "
        "relative on a random 4-link 3D tree.",
        f"- Computed in {seconds:.1f} s.",
        "",
        "## Summary",
        "",
        f"{len(checked)} formulas checked: {len(checked) - len(fails)} hold, {len(fails)} fail. "
        "The largest error is relative (see Method); `corrected` is the error of the corrected form "
        "and `matrix` that of the matrix method's element (`matrix_method/closed_forms/transitions.py`, division-free) "
        "on the same states.",
        "",
        "| formula | left side | verdict | largest error | corrected | matrix | models |",
        "|---|---|---|---|---|---|---|",
    ]
    for v in verdicts:
        f = v.formula
        L.append(
            f"| {f.equation} `{f.key}` | {f.label} | **{v.status}** | {_fmt(v.largest)} | "
            f"{_fmt(v.largest_corrected)} | {_fmt(v.largest_method)} | {_models(v) or '—'} |"
        )
    L += ["", "## What fails, and the corrected forms", ""]
    for v in fails:
        f = v.formula
        L += [
            f"### {f.equation} {f.label} (`{f.key}`): {v.status}",
            "",
            f"- Printed: `{f.latex}`",
            f"- Largest error as printed: {_fmt(v.largest)} ({_witness_summary(v)}).",
        ]
        if f.corrected_latex:
            L.append(
                f"- Corrected: `{f.corrected_latex}`; largest error {_fmt(v.largest_corrected)}"
                + (" (holds)." if v.largest_corrected <= TOLERANCE else " (STILL FAILS).")
            )
        else:
            L.append("- No corrected form is encoded.")
        if v.note:
            L.append(f"- {v.note}")
        L.append("")
    L += ["## How ambiguous print was read", ""]
    readings: dict[str, list[str]] = {}
    for v in verdicts:
        if v.formula.reading:
            readings.setdefault(v.formula.reading, []).append(f"{v.formula.equation} `{v.formula.key}`")
    for text, where in readings.items():
        L.append(f"- {', '.join(where)}: {text}")
    L += [
        "- (18), branched models: the planar elements of a model of the same structure carry the branch "
        "signs (the product s_i s_j, see the next section), and each transition multiplies them by "
        "functions of psi only, so the 3D elements carry the same signs; checked on random trees with "
        "random signs and several roots.",
        "",
    ]
    L += [
        "## Branch points: the sign rule of section 5 (`branch`)",
        "",
        f"Printed: `{printed.BRANCH_RULE.latex}` {printed.BRANCH_RULE.reading}",
        "",
        "| reading | verdict | largest error |",
        "|---|---|---|",
    ]
    for reading, v in branch.items():
        L.append(f"| {reading} | **{v.status}** | {_fmt(v.largest)} |")
    L += [
        "",
        "The reading that holds is the one the suite uses everywhere: an element carries the sign "
        "product s_i s_j (links on different sides of a branch point change sign) and vanishes for links "
        "on different branches; eq. (18) is checked on random trees with the planar elements carrying "
        "those signs, i.e. the transitions leave the signs unchanged.",
        "",
        "## Singular points of the printed eq. (18)",
        "",
        "Lines that divide by cos(phi_i - phi_j), cos phi_i, sin phi_i (or l_j) on the exactly singular "
        "state phi = (pi/2, 0, pi/4), l_3 = 0 of a 3-link spatial chain, misprinted lines in their "
        "corrected form (with the division) so that only the divisions are measured. `exact`: NaN entries of the printed form "
        "evaluated with exact arithmetic (as a computer-algebra system does: 0/0). `float`: at the nearest "
        "doubles, where only sin(0) is an exact zero; the error of its finite entries. `matrix`: the "
        "matrix method's division-free element there, against Pinocchio.",
        "",
        "| line | divides by | exact: NaN entries | float: NaN entries | float: error | matrix: error |",
        "|---|---|---|---|---|---|",
    ]
    for s in singular:
        L.append(
            f"| `{s.key}` | {', '.join(s.divides_by)} | {s.exact_nan} | {s.float_nan} | "
            f"{_fmt(s.float_error)} | {_fmt(s.matrix_error)} |"
        )
    L += [
        "",
        "## Effect on the gait of Fig. 6 (eq. 26, exo5-3d)",
        "",
        f"`matrix-paper` (eq. 18 exactly as printed) along {gait_['samples']} samples of one gait period, "
        "against Pinocchio:",
        "",
        "| rows | largest relative error (finite samples) | NaN samples |",
        "|---|---|---|",
    ]
    for block in ("phi", "psi", "l"):
        err, nan = gait_[block]
        L.append(f"| {block} | {_fmt(err)} | {nan} |")
    L += [
        "",
        f"`matrix` (corrected, division-free) along the same gait: {_fmt(gait_['matrix'])}.",
        "",
        "## Every formula in detail",
        "",
    ]
    for v in verdicts:
        f = v.formula
        L += [f"### {f.equation} {f.label} (`{f.key}`): {v.status}", "", f"Printed: `{f.latex}`", ""]
        if v.note and v.status == "holds":
            L += [f"Reading: {v.note}", ""]
        elif v.note and v.status == "not checkable":
            L += [v.note, ""]
        rows = [c for c in v.checks]
        if rows:
            L += ["| model | witness | error | relative | corrected | matrix | NaN |", "|---|---|---|---|---|---|---|"]
            for c in rows:
                if c.skipped:
                    L.append(f"| {c.model} | {c.witness} | skipped: {c.skipped} | | | | |")
                else:
                    L.append(
                        f"| {c.model} | {c.witness} | {_fmt(c.error)} | {_fmt(c.relative)} | "
                        f"{_fmt(c.corrected)} | {_fmt(c.method)} | {c.nan} |"
                    )
            L.append("")
    return "\n".join(L) + "\n"


def write_report(path=None, results: Results | None = None):
    """Compute every check (unless ``results`` are given) and write ``reports/errata.md``
    atomically; returns the path."""
    text = render(results or compute())
    return atomic_write(path or reporting.REPORTS / ERRATA, text)


def run(options: ReportOptions) -> int:
    """``exo-bench errata [--reports DIR]`` (also a suite job of ``exo-bench run``)."""
    path = write_report(options.folder / ERRATA)
    print(f"wrote {path}")
    return 0
