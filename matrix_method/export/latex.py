"""Eq. (5) / (17) in print: every matrix element in the paper's notation, as LaTeX.

Each element of eq. (5)/(17) is ``c_ij`` times a geometric factor of links ``i`` and ``j``
(:mod:`exo_bench.matrix_method.closed_forms.planar`, :mod:`exo_bench.matrix_method.closed_forms.transitions`: the closed forms are linear in ``c``),
with ``c_ij = s_i s_j mu_ij`` (:mod:`exo_bench.matrix_method.closed_forms.coefficients`, :mod:`exo_bench.models.mechanism.aggregates`), and each
gravity element ``P_i`` is ``nu_i s_i`` times one. :func:`element_parts` builds the geometric factors
with ``c = 1`` on related links, so an element prints as

    sign  x  coefficient  x  geometry,     e.g.  a^phi_13 = -(eta_3 + theta_4) l_1 l_3 C_13 C^psi_1 C^psi_3,

the sign being the branch sign product ``s_i s_j``, the coefficient ``mu_ij`` in the aggregates of
eq. (6) (``zeta_i, eta_i, theta_i`` with ``symbolic_parameters=True``) or its number, and links on
different branches giving ``0``. Notation (the paper's): ``C_i = cos phi_i``, ``S_i = sin phi_i``,
``C_ij = cos(phi_i - phi_j)``, ``S_ij = sin(phi_i - phi_j)``, ``C^psi_i = cos psi_i``,
``S^psi_i = sin psi_i``. Numbers print as the nearest double's shortest decimal.

:func:`eq4_rows` writes eq. (4) for a two-link planar model: the equations of the serial (upper signs)
and the branched (lower signs) model written once with ``±``/``∓``. The pages (Markdown and
standalone ``.tex``) are laid out in :mod:`exo_bench.bench.output.latex_document`.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
from sympy.printing.latex import LatexPrinter

from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling_entries
from exo_bench.matrix_method.symbolic import (
    generators,
    planar_entries,
    planar_gravity,
    spatial_entries,
    spatial_gravity,
    symbolic_aggregates,
    to_matrices,
)
from exo_bench.models.mechanism.aggregates import aggregates
from exo_bench.models.states.states import RATES, blocks, matrix_names
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import symbols_for

#: LaTeX of each matrix's elements (lower case, as the paper writes them) and of each block.
LETTER = {"A": "a", "B": "b", "Lambda": r"\lambda", "D": "d", "E": "e", "G": "g", "H": "h", "K": "k", "P": "p"}
MATRIX = {"A": "A", "B": "B", "Lambda": r"\Lambda", "D": "D", "E": "E", "G": "G", "H": "H", "K": "K", "P": "P"}
BLOCK = {"phi": r"\varphi", "psi": r"\psi", "l": "l"}
COORD = {"phi": r"\varphi", "psi": r"\psi", "l": "l"}


def aggregate_symbols(n: int) -> tuple[list[sp.Symbol], list[sp.Symbol], list[sp.Symbol]]:
    """``zeta_i, eta_i, theta_i`` of eq. (6) as named symbols (links from 1)."""
    mk = lambda p: [sp.Symbol(f"{p}{i}", positive=True) for i in range(1, n + 1)]
    return mk("zeta"), mk("eta"), mk("theta")


def _related(mech: Mechanism, i: int, j: int) -> bool:
    r = mech.ancestor_or_self
    return bool(i == j or r[i, j] or r[j, i])


@dataclass
class ElementParts:
    """Every element as ``coefficient x geometry``: ``geometry[block][name]`` (sympy Matrix, ``P``
    ``(n, 1)``), ``coefficient`` ``(n, n)`` (``c_ij``) and ``gravity`` ``(n,)`` (``nu_i s_i``), in the
    aggregate symbols or as exact numbers."""

    mechanism: Mechanism
    geometry: dict
    coefficient: list
    gravity: list
    symbolic_parameters: bool

    def element(self, block: str, name: str, i: int, j: int = 0) -> sp.Expr:
        if name == "P":
            return self.gravity[i] * self.geometry[block]["P"][i, 0]
        return self.coefficient[i][j] * self.geometry[block][name][i, j]


def element_parts(mech: Mechanism, symbolic_parameters: bool = False) -> ElementParts:
    """The geometric factors (``c = 1`` on related links, ``nu s = 1``) and the coefficients."""
    n = mech.nlinks
    G = generators(n, mech.dim, False)
    pairs = [(i, j) for i in range(n) for j in range(n) if _related(mech, i, j)]
    unit = [[1 if (i, j) in pairs else 0 for j in range(n)] for i in range(n)]
    now = planar_entries(G, unit, pairs)
    if mech.dim == 2:
        entries, grav = now, planar_gravity(G, [1] * n, range(n))
    else:
        straight = planar_entries(G, unit, pairs, straight=True)
        entries, grav = spatial_entries(G, now, straight, pairs), spatial_gravity(G, [1] * n, range(n))
    geometry = to_matrices(G, n, entries, grav)
    if symbolic_parameters:
        zeta, eta, theta = aggregate_symbols(n)
    else:
        zeta, eta, theta = symbolic_aggregates(mech, symbols_for(n, mech.dim), False)
    coef, grav_coef = signed_coupling_entries(mech, zeta, eta, theta, zero=sp.S.Zero)  # c_ij and nu_i s_i, once
    return ElementParts(mech, geometry, coef, grav_coef, symbolic_parameters)


def aggregate_definitions(mech: Mechanism) -> dict[sp.Symbol, sp.Expr]:
    """``zeta_i -> m_i1 n_i^2 + m_i2`` and so on (eq. (6)), in the shared mass symbols."""
    S = symbols_for(mech.nlinks, mech.dim)
    zeta, eta, theta = aggregate_symbols(mech.nlinks)
    out = {}
    for i in range(mech.nlinks):
        z, e, t = aggregates(*S.m[i], S.n[i])
        out.update({zeta[i]: z, eta[i]: e, theta[i]: t})
    return out


# ------------------------------------------------------------------------------ printing
def _index(*ks: int) -> str:
    return "".join(str(k) for k in ks) if all(k < 10 for k in ks) else ",".join(str(k) for k in ks)


def notation(mech: Mechanism) -> dict[sp.Expr, sp.Expr]:
    """The functions of the equations -> symbols named in the paper's notation (for ``xreplace``)."""
    S = symbols_for(mech.nlinks, mech.dim)
    n = mech.nlinks
    rep: dict = {}
    for i in range(n):
        rep[sp.cos(S.phi[i])] = sp.Symbol(f"C_{{{_index(i + 1)}}}")
        rep[sp.sin(S.phi[i])] = sp.Symbol(f"S_{{{_index(i + 1)}}}")
        if mech.dim == 3:
            rep[sp.cos(S.psi[i])] = sp.Symbol(f"C^{{\\psi}}_{{{_index(i + 1)}}}")
            rep[sp.sin(S.psi[i])] = sp.Symbol(f"S^{{\\psi}}_{{{_index(i + 1)}}}")
        for j in range(i + 1, n):
            C = sp.Symbol(f"C_{{{_index(i + 1, j + 1)}}}")
            Sn = sp.Symbol(f"S_{{{_index(i + 1, j + 1)}}}")
            rep[sp.cos(S.phi[i] - S.phi[j])] = C
            s = sp.sin(S.phi[i] - S.phi[j])
            if s.could_extract_minus_sign():
                rep[-s] = -Sn
            else:
                rep[s] = Sn
    return rep


def symbol_names(mech: Mechanism) -> dict[sp.Symbol, str]:
    """LaTeX of the shared symbols: ``l_{1}``, ``\\dot{\\varphi}_{1}``, ``\\zeta_{1}``, ``m_{10}``..."""
    S = symbols_for(mech.nlinks, mech.dim)
    out = {S.g: "g"}
    for i in range(mech.nlinks):
        k = _index(i + 1)
        out[S.l[i]] = f"l_{{{k}}}"
        out[S.dl[i]] = rf"\dot{{l}}_{{{k}}}"
        out[S.ddl[i]] = rf"\ddot{{l}}_{{{k}}}"
        out[S.dphi[i]] = rf"\dot{{\varphi}}_{{{k}}}"
        out[S.ddphi[i]] = rf"\ddot{{\varphi}}_{{{k}}}"
        if mech.dim == 3:
            out[S.dpsi[i]] = rf"\dot{{\psi}}_{{{k}}}"
            out[S.ddpsi[i]] = rf"\ddot{{\psi}}_{{{k}}}"
        for b in range(3):
            out[S.m[i][b]] = f"m_{{{_index(i + 1, b)}}}"
        out[S.n[i]] = f"n_{{{k}1}}" if i < 9 else f"n_{{{k},1}}"
    for name, syms in zip((r"\zeta", r"\eta", r"\theta"), aggregate_symbols(mech.nlinks)):
        for i, s in enumerate(syms):
            out[s] = f"{name}_{{{_index(i + 1)}}}"
    return out


def shortest(x: float) -> str:
    """A double as its shortest round-tripping decimal, in LaTeX (``1.5 \\cdot 10^{-5}``)."""
    text = repr(float(x))
    if "e" in text:
        mant, exp = text.split("e")
        return f"{mant} \\cdot 10^{{{int(exp)}}}"
    return text[:-2] if text.endswith(".0") else text


class _Printer(LatexPrinter):
    def _print_Float(self, expr):
        return shortest(float(expr))


def _numbers_as_floats(e: sp.Expr) -> sp.Expr:
    """Exact non-integer rationals as the nearest double (printed shortest)."""
    reps = {r: sp.Float(float(r), 17) for r in e.atoms(sp.Rational) if not r.is_Integer}
    return e.xreplace(reps)


class Latex:
    """The printer of one mechanism's expressions in the paper's notation."""

    def __init__(self, mech: Mechanism):
        self.mech = mech
        self.rep = notation(mech)
        names = symbol_names(mech)
        names.update({s: s.name for s in self.rep.values() if isinstance(s, sp.Symbol)})
        names.update({(-s): (-s).name for s in self.rep.values() if not isinstance(s, sp.Symbol)})
        self.printer = _Printer(
            {"symbol_names": {k: v for k, v in names.items() if isinstance(k, sp.Symbol)}, "mul_symbol": None}
        )

    def __call__(self, e) -> str:
        e = _numbers_as_floats(sp.sympify(e).xreplace(self.rep))
        return self.printer.doprint(e)

    def product(self, coefficient, geometry) -> str:
        """``sign coefficient geometry`` with the branch sign shown as a sign and a zero as 0."""
        if coefficient == 0 or geometry == 0:
            return "0"
        c, gm = sp.sympify(coefficient), sp.sympify(geometry)
        if not c.free_symbols:  # numbers: one expression, the number multiplied in
            return self(sp.expand(c * gm))
        sign = 1
        if c.could_extract_minus_sign():
            sign, c = -sign, -c
        if not gm.is_Add and gm.could_extract_minus_sign():
            sign, gm = -sign, -gm
        parts = []
        if c != 1:
            parts.append(rf"\left({self(c)}\right)" if c.is_Add else self(c))
        if gm != 1:
            parts.append(rf"\left({self(gm)}\right)" if gm.is_Add and c != 1 else self(gm))
        # a symbol before "\left(" would read as a function call: an explicit product there
        text = r" \cdot ".join(parts) if len(parts) > 1 and parts[-1].startswith(r"\left(") else " ".join(parts)
        return ("- " if sign < 0 else "") + (text or "1")


def element_name(block: str, name: str, i: int, j: int | None = None) -> str:
    idx = _index(i + 1) if j is None else _index(i + 1, j + 1)
    return f"{LETTER[name]}^{{{BLOCK[block]}}}_{{{idx}}}"


def elements(
    mech: Mechanism, symbolic_parameters: bool = False, parts: ElementParts | None = None
) -> dict[str, dict[str, dict[tuple, str]]]:
    """``block -> matrix -> (i, j) -> LaTeX`` of every element of eq. (5)/(17) (``P``: ``(i,)``)."""
    parts = parts or element_parts(mech, symbolic_parameters)
    L = Latex(mech)
    n = mech.nlinks
    out: dict = {}
    for block in blocks(mech.dim):
        out[block] = {}
        for name in matrix_names(mech.dim):
            out[block][name] = {
                (i, j): L.product(parts.coefficient[i][j], parts.geometry[block][name][i, j])
                for i in range(n)
                for j in range(n)
            }
        out[block]["P"] = {(i,): L.product(parts.gravity[i], parts.geometry[block]["P"][i, 0]) for i in range(n)}
    return out


# ------------------------------------------------------------------------------ eq. (4)
def _rate_latex(L: Latex, S, name: str, j: int) -> tuple[int, str]:
    factor, r = RATES[name]
    sym = lambda kind: L.printer.doprint(getattr(S, kind)[j])
    if len(r) == 1:
        return 1, sym("dd" + r[0])
    if r[0] == r[1]:
        return int(factor), sym("d" + r[0]) + "^{2}"
    return int(factor), sym("d" + r[0]) + " " + sym("d" + r[1])


def _terms(mech: Mechanism, parts: ElementParts, block: str, i: int):
    """Row ``i`` of block ``block`` as terms ``(key, sign, text)`` in the order of eq. (5)."""
    L = Latex(mech)
    S = symbols_for(mech.nlinks, mech.dim)
    out = []
    for name in matrix_names(mech.dim):
        for j in range(mech.nlinks):
            c, gm = parts.coefficient[i][j], parts.geometry[block][name][i, j]
            if c == 0 or gm == 0:
                continue
            k, rate = _rate_latex(L, S, name, j)
            sign = -1 if c.could_extract_minus_sign() else 1
            c = -c if sign < 0 else c
            if not gm.is_Add and gm.could_extract_minus_sign():
                sign, gm = -sign, -gm
            body = " ".join(
                x
                for x in [
                    str(k) if k != 1 else "",
                    rf"\left({L(c)}\right)" if c.is_Add else ("" if c == 1 else L(c)),
                    rf"\left({L(gm)}\right)" if gm.is_Add else ("" if gm == 1 else L(gm)),
                    rate,
                ]
                if x
            )
            out.append(((name, j), sign, body))
    c, gm = parts.gravity[i], parts.geometry[block]["P"][i, 0]
    if c != 0 and gm != 0:
        sign = -1 if c.could_extract_minus_sign() else 1
        c = -c if sign < 0 else c
        if not gm.is_Add and gm.could_extract_minus_sign():
            sign, gm = -sign, -gm
        body = " ".join(
            x
            for x in [
                rf"\left({L(c)}\right)" if c.is_Add else L(c),
                "g",
                rf"\left({L(gm)}\right)" if gm.is_Add else L(gm),
            ]
            if x
        )
        out.append((("P", i), sign, body))
    return out


def force_latex(block: str, i: int) -> str:
    return f"F_{{{_index(i + 1)}}}" if block == "l" else f"M^{{{BLOCK[block]}}}_{{{_index(i + 1)}}}"


def eq4_rows(serial: Mechanism, branched: Mechanism) -> list[str]:
    """Eq. (4): the equations of the serial (upper signs) and branched (lower signs) two-link planar
    models written once: a term whose sign differs between them carries ``\\pm`` or ``\\mp``."""
    if not (serial.dim == branched.dim == 2 and serial.nlinks == branched.nlinks == 2):
        raise ValueError("eq. (4): expected two two-link planar models")
    a, b = element_parts(serial, True), element_parts(branched, True)
    rows = []
    for block in blocks(2):
        for i in range(2):
            ta, tb = _terms(serial, a, block, i), _terms(branched, b, block, i)
            if [(k, body) for k, _, body in ta] != [(k, body) for k, _, body in tb]:
                raise ValueError("eq. (4): the two models differ in more than signs")
            text = []
            for n_, ((_, sa, body), (_, sb, _)) in enumerate(zip(ta, tb)):
                op = ("+" if sa > 0 else "-") if sa == sb else (r"\pm" if sa > 0 else r"\mp")
                text.append((op if n_ or op != "+" else "") + " " + body)
            rows.append(" ".join(text).strip() + f" &= {force_latex(block, i)}")
    return rows
