"""The equations of motion as a page: every element of eq. (5)/(17) in the paper's notation
(:mod:`exo_bench.matrix_method.export.latex`), as Markdown (``$$`` blocks that render on a code-hosting
site) or a standalone ``.tex`` file, with the legend of the aggregates and, for a two-link planar model,
eq. (4) with both signs."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from exo_bench.models.files import latex_text, markdown_code
from exo_bench.matrix_method.export.latex import (
    BLOCK,
    MATRIX,
    ElementParts,
    element_name,
    Latex,
    aggregate_definitions,
    aggregate_symbols,
    element_parts,
    elements,
    eq4_rows,
    shortest,
)
from exo_bench.models.states.states import blocks, matrix_names
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import symbols_for


@dataclass(frozen=True)
class Name:
    """A user's name (a mechanism's, a scene's) inside a page's prose: written by the page's encoder,
    a Markdown code span (:func:`exo_bench.models.files.markdown_code`) or LaTeX text
    (:func:`exo_bench.models.files.latex_text` in ``\\texttt``), never read as markup."""

    value: str


#: Prose of a page: the suite's own text (Markdown with ``$...$`` math) and names.
Prose = Sequence["str | Name"]


def md_prose(parts: Prose) -> str:
    """Prose as Markdown: the suite's text as it is, each name a code span."""
    return "".join(p if isinstance(p, str) else markdown_code(p.value) for p in parts)


def tex_prose(parts: Prose) -> str:
    """Prose as LaTeX: the suite's text by :func:`_tex_text`, each name as escaped text in ``\\texttt``."""
    return "".join(_tex_text(p) if isinstance(p, str) else r"\texttt{" + latex_text(p.value) + "}" for p in parts)


NOTATION_TEXT = (
    r"$C_i = \cos\varphi_i$, $S_i = \sin\varphi_i$, $C_{ij} = \cos(\varphi_i - \varphi_j)$, "
    r"$S_{ij} = \sin(\varphi_i - \varphi_j)$, $C^{\psi}_i = \cos\psi_i$, $S^{\psi}_i = \sin\psi_i$"
)


def legend(mech: Mechanism, symbolic_parameters: bool) -> list[str]:
    """The aggregates of eq. (6) in the masses, and the coupling ``mu_ij`` (signs ``s_i s_j``)."""
    L = Latex(mech)
    n = mech.nlinks
    defs = aggregate_definitions(mech)
    lines = []
    for _i, (z, e, t) in enumerate(zip(*aggregate_symbols(n))):
        vals = []
        for sym in (z, e, t):
            value = defs[sym].xreplace(symbols_for(n, mech.dim).parameter_values(mech))
            vals.append(f"{L.printer.doprint(sym)} = {L(defs[sym])} = {shortest(float(value))}")
        lines.append(r", \quad ".join(vals))
    return lines


def document(
    mech: Mechanism,
    symbolic_parameters: bool,
    kind: str,
    header: str,
    title: Prose | None = None,
    matrices_shown: tuple[str, ...] | None = None,
    eq4: tuple[Mechanism, Mechanism] | None = None,
    parts: ElementParts | None = None,
) -> str:
    """The Markdown page (``kind="md"``) or standalone LaTeX (``kind="tex"``) of every element of
    eq. (5)/(17) of ``mech`` (``matrices_shown``: a subset of the matrices, ``P`` included by name).
    ``header``: Markdown provenance text (the Markdown page only). ``eq4``: the serial and the
    branched two-link models, to write eq. (4) with both signs. ``title`` and every name in the prose
    are :class:`Name` parts, encoded for the page's language."""
    if kind not in ("md", "tex"):
        raise ValueError(f"kind: expected 'md' or 'tex', got {kind!r}")
    parts = parts or element_parts(mech, symbolic_parameters)
    els = elements(mech, symbolic_parameters, parts)
    names = matrix_names(mech.dim) + ("P",)
    shown = tuple(m for m in names if matrices_shown is None or m in matrices_shown)
    md = kind == "md"
    title = title or ("Equations of motion of ", Name(mech.name))
    out: list[str] = []

    def heading(level: int, text: str):
        if md:
            out.extend(["#" * level + " " + text, ""])
        else:
            cmd = {1: "section*", 2: "subsection*", 3: "subsubsection*"}.get(level, "paragraph*")
            out.extend([f"\\{cmd}{{{_tex_text(text)}}}", ""])

    def para(*parts: str | Name):
        out.extend([md_prose(parts) if md else tex_prose(parts), ""])

    def math(lines: list[str]):
        body = " \\\\\n".join(lines)
        if md:
            out.extend(["$$", "\\begin{aligned}", body, "\\end{aligned}", "$$", ""])
        else:
            out.extend(["\\begin{align*}", body, "\\end{align*}", ""])

    if md:
        out.extend([f"# {md_prose(title)}", "", header, ""])
    s = mech.sign
    rates = (
        "A phi'' + B psi'' + Lambda l'' + D (phi'^2) + E (psi'^2) + 2 G (phi' psi') + 2 H (phi' l') + 2 K (psi' l') + g P"
        if mech.dim == 3
        else "A phi'' + Lambda l'' + D (phi'^2) + 2 H (phi' l') + g P"
    )
    para(
        "Mechanism ",
        Name(mech.name),
        f": {mech.dim}D, {mech.nlinks} link(s), parents {list(mech.parent)} (-1: the support "
        f"point), branch signs {list(s)}. Eq. ({5 if mech.dim == 2 else 17}) of Borisov & Chigarev, block k "
        f"(k = {', '.join(blocks(mech.dim))}): `{rates} = M_k` (`F` for k = l), every matrix composed by the matrix "
        "method from its closed forms (`exo_bench.matrix_method`) and checked against Pinocchio and Lagrange "
        "(tests/test_equations_export.py). Right-hand sides are generalised forces of the absolute angles "
        "(the paper's joint moments: `M_1 - M_2` for phi_1 of a chain).",
    )
    para(
        "Notation: " + NOTATION_TEXT + "; dots are time derivatives. Every element is the sign product "
        "s_i s_j (a minus sign at a branch point), the coefficient mu_ij of eq. (6) in the aggregates "
        "(zeta_i, eta_i, theta_i), and a geometric factor; links on different branches give 0. "
        + (
            "Coefficients are named symbols (values below)."
            if symbolic_parameters
            else "Coefficients are this mechanism's numbers (the nearest double of the exact value)."
        )
    )
    heading(2, "Aggregates (eq. (6))")
    math([ln for ln in legend(mech, symbolic_parameters)])
    if eq4 is not None:
        heading(2, "Eq. (4): the two-link model, upper signs serial (Fig. 2a), lower signs branched (Fig. 2b)")
        which = "upper" if mech.sign[1] > 0 else "lower"
        para(
            "This page's model ",
            Name(mech.name),
            f" takes the {which} signs. Composed here from the closed forms; "
            "reports/errata.md compares it with eq. (4) as printed.",
        )
        math(eq4_rows(*eq4))
    for block in blocks(mech.dim):
        heading(2, f"Block {block}: the equations of " + ("F" if block == "l" else f"M_{block}"))
        for name in shown:
            items = els[block][name]
            label = f"${MATRIX[name]}_{{{BLOCK[block]}}}$" if md else f"{MATRIX[name]}_{BLOCK[block]}"
            heading(3, f"{name}_{block}" if not md else label)
            if name == "P":
                math([f"{element_name(block, name, i)} &= {v}" for (i,), v in items.items()])
            else:
                math([f"{element_name(block, name, i, j)} &= {v}" for (i, j), v in items.items()])
    if md and matrices_shown is not None and set(shown) != set(names):
        para(f"This page shows {', '.join(shown)}; the .tex file beside it has every matrix.")
    text = "\n".join(out)
    if md:
        return text
    return _tex_wrap(title, text)


def _tex_text(text: str) -> str:
    """The suite's own Markdown prose as LaTeX text: backticks dropped, special characters escaped
    (math kept). Never a user's name: those are :class:`Name` parts (:func:`tex_prose`)."""
    out, math_mode = [], False
    for ch in text.replace("`", ""):
        if ch == "$":
            math_mode = not math_mode
            out.append(ch)
        elif not math_mode and ch in "_&%#^":
            out.append({"^": r"\^{}"}.get(ch, "\\" + ch))
        elif not math_mode and ch == "'":
            out.append("'")
        else:
            out.append(ch)
    return "".join(out)


def _tex_wrap(title: Prose, body: str) -> str:
    return "\n".join(
        [
            r"\documentclass[10pt]{article}",
            r"\usepackage[a4paper,landscape,margin=1cm]{geometry}",
            r"\usepackage{amsmath}",
            r"\allowdisplaybreaks",
            r"\begin{document}",
            rf"\section*{{{tex_prose(title)}}}",
            "",
            body,
            r"\end{document}",
            "",
        ]
    )
