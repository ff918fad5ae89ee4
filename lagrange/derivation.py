"""Lagrange's equations of the second kind, derived with sympy from the point masses' T and Pi.

This is the suite's independent symbolic check of the paper's matrix method: it never uses the
closed forms (mu, nu, eq. 6). Positions are built from the geometry alone, link by link down the
tree (:mod:`models.mechanism`): link ``i`` starts at the end of its parent and its masses sit at
fractions ``0, n_i, 1`` of ``w_i = sign_i l_i u_i``. Then

* ``T = 1/2 sum_ib m_ib |v_ib|^2`` with ``v_ib = sum_a (d r_ib / d q_a) qd_a``,
* ``Pi = g sum_ib m_ib h_ib`` (``h`` the last Cartesian coordinate),
* Lagrange II, term by term: ``tau_a = sum_b (d2T/dqd_a dq_b) qd_b + sum_b (d2T/dqd_a dqd_b) qdd_b
  - dT/dq_a + dPi/dq_a``.

**Engines.** ``engine="poly"`` (the default) does every step in a sparse polynomial ring
(:func:`sympy.polys.rings.ring`) over the rationals whose generators are ``sin``/``cos`` of the
angles, the lengths, rates, accelerations, masses, fractions and ``g``; ``d/dphi`` acts by the
chain rule ``d sin(phi) = cos(phi) dphi``, ``d cos(phi) = -sin(phi) dphi``. ``engine="expr"`` is
the textbook route: the same T and Pi as sympy expressions, ``sympy.diff`` and ``sympy.expand``;
it gives identical equations about a hundred times slower and exists so that a benchmark can
time the plain computer-algebra derivation the paper timed in Mathematica.

**Normal form.** Results are reduced modulo ``sin^2 + cos^2 = 1`` by ``cos(x)^2 -> 1 - sin(x)^2``
(every ``cos`` appears at most to the first power). This normal form is canonical, so two
polynomial expressions in sines and cosines are equal exactly when their normal forms are;
:func:`canonical_form` brings any expression (e.g. with ``cos(phi_i - phi_j)``) to it.

**Matrix form** (eqs. 5 and 17): :func:`extract_matrices` reads the paper's matrices off the
equations term by term and raises :class:`FormViolation` on any product of rates that the form
does not have (e.g. ``dphi_i dphi_j`` with ``i != j``, or ``dl_j^2``).

**Parameters and caching.** The symbolic form is derived once per *structure* (dim, parent,
sign and which masses are zero; zero masses are structural zeros) with masses ``m{i}_{b}``,
fractions ``n{i}`` and ``g`` as symbols. ``symbolic_parameters=False`` then substitutes the
mechanism's numbers as **exact sympy Rationals** equal to the float64 values (so the 50-digit
reference of :mod:`lagrange.reference` sees exactly the float model).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import sympy as sp
from sympy import QQ
from sympy.polys.rings import ring

from exo_bench.lagrange.budget import BudgetAlarm, BudgetExceeded, Deadline, time_budget
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.symbols import Symbols, symbols_for

#: blocks of coordinates (rows of the matrix form), in block order
BLOCKS = {2: ("phi", "l"), 3: ("phi", "psi", "l")}
#: names of the matrices of eq. (5) (2D) and eq. (17) (3D)
MATRIX_NAMES = {2: ("A", "Lambda", "D", "H", "P"), 3: ("A", "B", "Lambda", "D", "E", "G", "H", "K", "P")}
ENGINES = ("poly", "expr")


class FormViolation(ValueError):
    """An equation has a term that the paper's matrix form (eqs. 5, 17) cannot hold."""


# ------------------------------------------------------------------ structure
@dataclass(frozen=True)
class Structure:
    """What the symbolic derivation depends on: the tree, the signs and the zero masses."""

    dim: int
    parent: tuple[int, ...]
    sign: tuple[int, ...]
    zero_masses: tuple[tuple[bool, bool, bool], ...]

    @property
    def nlinks(self) -> int:
        return len(self.parent)


def structure_of(mech: Mechanism) -> Structure:
    return Structure(mech.dim, mech.parent, mech.sign,
                     tuple(tuple(m == 0.0 for m in ms) for ms in mech.masses))


# ------------------------------------------------------------------ result
@dataclass(frozen=True, eq=False)
class Derivation:
    """Lagrange II for one mechanism (or one structure, with symbolic parameters).

    ``equations[a]`` is the generalised force of coordinate ``a`` (block order, as ``tau``);
    ``matrices[block][name]`` the paper's matrices (``P`` is ``(n, 1)`` and excludes ``g``);
    ``seconds`` the wall time of each phase when this result was first computed.
    """

    structure: Structure
    symbols: Symbols
    equations: tuple[sp.Expr, ...]
    matrices: dict[str, dict[str, sp.Matrix]]
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    symbolic_parameters: bool
    engine: str
    seconds: dict[str, float] = field(default_factory=dict)
    ring_form: "_RingForm | None" = field(default=None, repr=False)   # internal: the ring elements
    values: dict = field(default_factory=dict, repr=False)   # the substituted parameter values ({} if symbolic)

    @property
    def g(self) -> sp.Expr:
        """The gravity factor in front of ``P``: the symbol ``g``, or its substituted value."""
        return self.values.get(self.symbols.g, self.symbols.g)

    @property
    def dim(self) -> int:
        return self.structure.dim

    @property
    def nlinks(self) -> int:
        return self.structure.nlinks

    @cached_property
    def mass_matrix(self) -> sp.Matrix:
        """``(dof, dof)``: row block k is ``[A_k, B_k, Lambda_k]`` (``[A_k, Lambda_k]`` in 2D)."""
        cols = ("A", "B", "Lambda") if self.dim == 3 else ("A", "Lambda")
        return sp.Matrix.vstack(*[sp.Matrix.hstack(*[self.matrices[k][c] for c in cols])
                                  for k in BLOCKS[self.dim]])


# ------------------------------------------------------------------ polynomial ring
class _Ring:
    """The polynomial ring of the derivation: generators ``sin``/``cos`` of every angle, then
    lengths, rates, accelerations, masses, fractions and ``g``."""

    def __init__(self, S: Symbols, dim: int, extra: tuple[sp.Symbol, ...] = ()):
        angles = list(S.phi) + list(S.psi)
        trig = [f(x) for x in angles for f in (sp.sin, sp.cos)]
        params = [m for ms in S.m for m in ms] + list(S.n) + [S.g]
        gens = trig + list(S.l) + list(S.qd) + list(S.qdd) + params + list(extra)
        self.R, *G = ring(gens, QQ)
        self.gen = dict(zip(gens, G))
        self.index = {x: k for k, x in enumerate(gens)}
        self.S, self.dim = S, dim
        # (sin, cos) ring generators of every angle coordinate, by coordinate index
        self.trig_pairs = [(self.gen[sp.sin(x)], self.gen[sp.cos(x)]) for x in angles]
        self.trig_index = [(self.index[sp.sin(x)], self.index[sp.cos(x)]) for x in angles]
        self.nangles = len(angles)
        self.q_l = [self.gen[x] for x in S.l]
        self.qd = [self.gen[x] for x in S.qd]
        self.qdd = [self.gen[x] for x in S.qdd]
        self._one_minus_s2: dict[int, list] = {}

    def d_dq(self, p, a: int):
        """Partial derivative with respect to coordinate ``a`` (block order)."""
        if a < self.nangles:
            s, c = self.trig_pairs[a]
            return p.diff(s) * c - p.diff(c) * s   # d sin = cos, d cos = -sin
        return p.diff(self.q_l[a - self.nangles])

    def unit(self, i: int):
        """``u_i``: ``(cos phi, sin phi)`` in 2D, eq. (7) in 3D."""
        sph, cph = self.trig_pairs[i]
        if self.dim == 2:
            return [cph, sph]
        n = len(self.S.phi)
        sps, cps = self.trig_pairs[n + i]
        return [cps * cph, cps * sph, sps]

    def reduce(self, p):
        """Normal form modulo ``sin^2 + cos^2 = 1``: every ``cos(x)^2`` becomes ``1 - sin(x)^2``."""
        R = self.R
        keep: dict = {}
        out = R.zero
        for monom, coeff in p.items():
            if all(monom[c] < 2 for _, c in self.trig_index):
                keep[monom] = keep.get(monom, 0) + coeff
                continue
            e = list(monom)
            factor = R.one
            for k, (s, c) in enumerate(self.trig_index):
                if e[c] >= 2:
                    half = e[c] // 2
                    e[c] -= 2 * half
                    factor *= self._power(k, half)
            out += R.from_dict({tuple(e): coeff}) * factor
        return out + R.from_dict({m: c for m, c in keep.items() if c})

    def _power(self, k: int, half: int):
        """``(1 - sin^2)^half`` of angle ``k``, cached."""
        pw = self._one_minus_s2.setdefault(k, [self.R.one])
        s = self.trig_pairs[k][0]
        while len(pw) <= half:
            pw.append(pw[-1] * (1 - s**2))
        return pw[half]

    def substitute(self, p, values: dict[sp.Symbol, sp.Rational]):
        """``p`` with the given generators replaced by numbers (their exponents set to zero)."""
        vals = [(self.index[x], QQ.from_sympy(v)) for x, v in values.items() if x in self.index]
        out: dict = {}
        for monom, coeff in p.items():
            m = list(monom)
            for k, v in vals:
                if m[k]:
                    coeff = coeff * v ** m[k]
                    m[k] = 0
            if coeff:
                m = tuple(m)
                out[m] = out.get(m, 0) + coeff
        return self.R.from_dict({m: c for m, c in out.items() if c})

    def from_expr(self, expr: sp.Expr):
        """An expression polynomial in the generators (after ``expand``) as a ring element."""
        return self.R.from_expr(sp.expand(expr))


@dataclass
class _Energies:
    T: object
    Pi: object


@dataclass(frozen=True, eq=False)
class _RingForm:
    """The ring elements behind a symbolic :class:`Derivation` (numbers are substituted here)."""

    ring: _Ring
    equations: list
    matrices: dict[str, dict[str, list]]
    T: object
    Pi: object


def _energies_poly(st: Structure, rg: _Ring, dl: Deadline) -> _Energies:
    """T and Pi of the point masses, positions built down the tree from the geometry."""
    R, S, n, dim = rg.R, rg.S, st.nlinks, st.dim
    dof = dim * n
    g = rg.gen[S.g]
    ends: list[list] = []
    T, Pi = R.zero, R.zero
    for i in range(n):
        p = st.parent[i]
        start = ends[p] if p >= 0 else [R.zero] * dim                  # end of the parent, or O
        w = [st.sign[i] * rg.q_l[i] * x for x in rg.unit(i)]            # w_i = s_i l_i u_i
        ends.append([a + b for a, b in zip(start, w)])
        for b, frac in enumerate((R.zero, rg.gen[S.n[i]], R.one)):
            dl.check()
            if st.zero_masses[i][b]:
                continue
            m = rg.gen[S.m[i][b]]
            r = [a + frac * c for a, c in zip(start, w)]                 # r_ib = start + n_ib w_i
            v = [sum((rg.d_dq(x, a) * rg.qd[a] for a in range(dof)), R.zero) for x in r]
            T += m * sum((x * x for x in v), R.zero) / 2                  # 1/2 m |v|^2
            Pi += m * g * r[-1]                                           # m g h
    return _Energies(rg.reduce(T), Pi)


def _lagrange_poly(rg: _Ring, E: _Energies, dof: int, dl: Deadline) -> list:
    """Lagrange II for every coordinate, in the ring."""
    eqs = []
    for a in range(dof):
        dl.check()
        p_a = E.T.diff(rg.qd[a])                                          # dT/dqd_a
        # First term: d/dt dT/dqd_a = sum_b d2T/dqd_a dq_b qd_b + sum_b d2T/dqd_a dqd_b qdd_b
        ddt = sum((rg.d_dq(p_a, b) * rg.qd[b] for b in range(dof)), rg.R.zero)
        ddt += sum((p_a.diff(rg.qd[b]) * rg.qdd[b] for b in range(dof)), rg.R.zero)
        # Second term: - dT/dq_a; third term: + dPi/dq_a
        eqs.append(rg.reduce(ddt - rg.d_dq(E.T, a) + rg.d_dq(E.Pi, a)))
    return eqs


def _unit_expr(S: Symbols, i: int, dim: int) -> sp.Matrix:
    if dim == 2:
        return sp.Matrix([sp.cos(S.phi[i]), sp.sin(S.phi[i])])
    c = sp.cos(S.psi[i])
    return sp.Matrix([c * sp.cos(S.phi[i]), c * sp.sin(S.phi[i]), sp.sin(S.psi[i])])


def _derive_expr(st: Structure, rg: _Ring, dl: Deadline) -> tuple[_Energies, list]:
    """The textbook route: T and Pi as sympy expressions, ``sympy.diff`` and ``sympy.expand``."""
    S, n, dim = rg.S, st.nlinks, st.dim
    q, qd, qdd = S.q, S.qd, S.qdd
    ends: list[sp.Matrix] = []
    T, Pi = sp.Integer(0), sp.Integer(0)
    for i in range(n):
        p = st.parent[i]
        start = ends[p] if p >= 0 else sp.zeros(dim, 1)
        w = st.sign[i] * S.l[i] * _unit_expr(S, i, dim)
        ends.append(start + w)
        for b, frac in enumerate((0, S.n[i], 1)):
            dl.check()
            if st.zero_masses[i][b]:
                continue
            r = start + frac * w
            v = r.jacobian(q) * sp.Matrix(qd)
            T += S.m[i][b] * v.dot(v) / 2
            Pi += S.m[i][b] * S.g * r[-1]
    eqs = []
    for a in range(len(q)):
        dl.check()
        p_a = sp.diff(T, qd[a])
        ddt = sum(sp.diff(p_a, q[b]) * qd[b] + sp.diff(p_a, qd[b]) * qdd[b] for b in range(len(q)))
        eqs.append(rg.reduce(rg.from_expr(ddt - sp.diff(T, q[a]) + sp.diff(Pi, q[a]))))
    return _Energies(rg.reduce(rg.from_expr(T)), rg.from_expr(Pi)), eqs


def _derive_symbolic(st: Structure, engine: str, dl: Deadline) -> Derivation:
    S = symbols_for(st.nlinks, st.dim)
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    rg = _Ring(S, st.dim)
    if engine == "poly":
        E = _energies_poly(st, rg, dl)
        t1 = time.perf_counter()
        seconds["energies"] = t1 - t0
        eqs = _lagrange_poly(rg, E, st.dim * st.nlinks, dl)
        seconds["lagrange"] = time.perf_counter() - t1
    else:
        E, eqs = _derive_expr(st, rg, dl)
        seconds["lagrange"] = time.perf_counter() - t0
    t2 = time.perf_counter()
    mats = _extract_ring(rg, eqs, dl)
    seconds["matrices"] = time.perf_counter() - t2
    form = _RingForm(rg, eqs, mats, E.T, E.Pi)
    out = _from_ring(st, form, True, engine, seconds)
    seconds["total"] = time.perf_counter() - t0
    return out


def _from_ring(st: Structure, form: _RingForm, symbolic: bool, engine: str, seconds: dict,
               values: dict | None = None) -> Derivation:
    """The sympy expressions of a ring form."""
    return Derivation(st, form.ring.S, tuple(e.as_expr() for e in form.equations), _matrices_expr(form.matrices),
                      form.T.as_expr(), form.Pi.as_expr(), symbolic, engine, seconds, form, values or {})


# ------------------------------------------------------------------ matrix form
# which matrix holds a term, and the factor in front of it in the form (2G, 2H, 2K)
_ACCEL = {"phi": "A", "psi": "B", "l": "Lambda"}
_SQUARE = {"phi": "D", "psi": "E"}
_PAIR = {frozenset(("phi", "psi")): "G", frozenset(("phi", "l")): "H", frozenset(("psi", "l")): "K"}


def _rate_slots(rg: _Ring) -> dict[int, tuple[str, str, int]]:
    """ring generator index of every rate and acceleration -> (order 'd'/'dd', block, link)."""
    S = rg.S
    out = {}
    for blk, d, dd in (("phi", S.dphi, S.ddphi), ("psi", S.dpsi, S.ddpsi), ("l", S.dl, S.ddl)):
        for j, (x, y) in enumerate(zip(d, dd)):
            out[rg.index[x]] = ("d", blk, j)
            out[rg.index[y]] = ("dd", blk, j)
    return out


def _classify(items: list[tuple[tuple[str, str, int], int]]) -> tuple[str, int, int] | None:
    """(matrix, column, factor in the form) of a product of rates given as ((order, block, link),
    exponent) pairs; None if the form has no slot for it."""
    if len(items) == 1:
        (order, blk, j), e = items[0]
        if order == "dd" and e == 1:
            return _ACCEL[blk], j, 1          # A, B, Lambda: accelerations
        if order == "d" and e == 2 and blk in _SQUARE:
            return _SQUARE[blk], j, 1         # D, E: squared angle rates
        return None
    if len(items) == 2:
        ((o1, b1, j1), e1), ((o2, b2, j2), e2) = items
        if o1 == o2 == "d" and e1 == e2 == 1 and j1 == j2 and b1 != b2:
            return _PAIR[frozenset((b1, b2))], j1, 2   # 2G, 2H, 2K: products of one link's rates
    return None


def _extract_ring(rg: _Ring, eqs: list, deadline: Deadline | None = None) -> dict[str, dict[str, list]]:
    """The matrix form of ring equations: ``{block: {name: rows of ring elements}}``."""
    S, R = rg.S, rg.R
    dim = 3 if S.psi else 2
    n = len(S.phi)
    slots = _rate_slots(rg)
    gi = rg.index[S.g]
    zero_out = sorted(slots) + [gi]
    out: dict[str, dict[str, list]] = {}
    for kb, blk in enumerate(BLOCKS[dim]):
        acc: dict[tuple[str, int, int], dict] = {}
        for i in range(n):
            if deadline is not None:
                deadline.check()
            for monom, coeff in eqs[kb * n + i].items():
                where = lambda: f"equation {blk}{i + 1}: term {R.from_dict({monom: coeff}).as_expr()}"
                items = [(slots[k], monom[k]) for k in slots if monom[k]]
                if not items:
                    if monom[gi] != 1:
                        raise FormViolation(f"{where()}: a term without rates must be g times a function of "
                                            "the coordinates (the g P column)")
                    slot = ("P", i, 0)
                    factor = 1
                else:
                    if monom[gi]:
                        raise FormViolation(f"{where()}: g times rates fits no matrix of the form")
                    found = _classify(items)
                    if found is None:
                        raise FormViolation(f"{where()}: this product of rates fits no matrix of the form "
                                            "(only accelerations, squared angle rates of one link and "
                                            "products of one link's own rates appear)")
                    name, j, factor = found
                    slot = (name, i, j)
                m = list(monom)
                for k in zero_out:
                    m[k] = 0
                d = acc.setdefault(slot, {})
                m = tuple(m)
                d[m] = d.get(m, 0) + coeff / QQ(factor)
        mats = {name: [[R.zero] * (1 if name == "P" else n) for _ in range(n)] for name in MATRIX_NAMES[dim]}
        for (name, i, j), d in acc.items():
            mats[name][i][j] = R.from_dict({m: c for m, c in d.items() if c})
        out[blk] = mats
    return out


def _matrices_expr(mats: dict[str, dict[str, list]]) -> dict[str, dict[str, sp.Matrix]]:
    return {blk: {name: sp.Matrix([[x.as_expr() for x in row] for row in rows]) for name, rows in m.items()}
            for blk, m in mats.items()}


def extract_matrices(equations, symbols: Symbols, deadline: Deadline | None = None
                     ) -> dict[str, dict[str, sp.Matrix]]:
    """The paper's matrices (eq. 5 in 2D, eq. 17 in 3D) read off equations given in block order.

    Row ``i`` of block ``k`` is ``sum_j (A ddphi_j + B ddpsi_j + Lambda ddl_j + D dphi_j^2
    + E dpsi_j^2 + 2 G dphi_j dpsi_j + 2 H dphi_j dl_j + 2 K dpsi_j dl_j)[i, j] + g P[i]``.
    ``g`` must be a symbol in the equations (it tells the potential terms apart); the
    equations must be polynomials in the sines and cosines of the angles, the lengths, rates,
    accelerations and the shared parameter symbols. Entries come out in the normal form of
    :func:`canonical_form`.

    Raises :class:`FormViolation` naming the equation and the term when a term fits no slot:
    a product of rates of two different links, ``dl_j^2``, a rate times an acceleration, a
    rate-free term without ``g``, or ``g`` times a rate.
    """
    S = symbols
    dim = 3 if S.psi else 2
    n = len(S.phi)
    if len(equations) != dim * n:
        raise ValueError(f"extract_matrices: field 'equations': expected {dim * n} equations "
                         f"(block order {', '.join(BLOCKS[dim])}), got {len(equations)}")
    rg = _Ring(S, dim)
    eqs = []
    for k, e in enumerate(equations):
        try:
            eqs.append(rg.reduce(rg.from_expr(sp.expand_trig(sp.sympify(e)))))
        except (ValueError, sp.polys.polyerrors.PolynomialError) as err:
            raise ValueError(f"extract_matrices: equation {k + 1}: expected a polynomial in sines and cosines "
                             f"of the angles, lengths, rates and the shared parameter symbols: {err}") from None
    return _matrices_expr(_extract_ring(rg, eqs, deadline))


def rebuild_equations(matrices: dict[str, dict[str, sp.Matrix]], symbols: Symbols, g: sp.Expr | None = None
                      ) -> tuple[sp.Expr, ...]:
    """The equations written back from the matrix form (the inverse of :func:`extract_matrices`);
    ``g`` defaults to the symbol (pass :attr:`Derivation.g` for substituted parameters)."""
    S = symbols
    g = S.g if g is None else g
    dim = 3 if S.psi else 2
    n = len(S.phi)
    out = []
    for blk in BLOCKS[dim]:
        M = matrices[blk]
        for i in range(n):
            e = g * M["P"][i, 0]
            for j in range(n):
                e += M["A"][i, j] * S.ddphi[j] + M["Lambda"][i, j] * S.ddl[j]
                e += M["D"][i, j] * S.dphi[j] ** 2 + 2 * M["H"][i, j] * S.dphi[j] * S.dl[j]
                if dim == 3:
                    e += M["B"][i, j] * S.ddpsi[j] + M["E"][i, j] * S.dpsi[j] ** 2
                    e += 2 * M["G"][i, j] * S.dphi[j] * S.dpsi[j] + 2 * M["K"][i, j] * S.dpsi[j] * S.dl[j]
            out.append(e)
    return tuple(out)


def canonical_form(expr: sp.Expr, symbols: Symbols) -> sp.Expr:
    """The normal form of an expression polynomial in sines and cosines of the angles (after
    ``expand_trig``, so ``cos(phi1 - phi2)`` is allowed): expanded, every ``cos^2`` replaced by
    ``1 - sin^2``. Two such expressions are equal exactly when their normal forms are."""
    dim = 3 if symbols.psi else 2
    e = sp.expand(sp.expand_trig(sp.sympify(expr)))
    angles = set(symbols.phi) | set(symbols.psi)
    known = set(_Ring(symbols, dim).index)
    # Symbols outside the shared set (a caller's own parameters) become extra generators.
    extra = tuple(sorted(e.free_symbols - known - angles, key=str))
    rg = _Ring(symbols, dim, extra)
    try:
        p = rg.R.from_expr(e)
    except (ValueError, sp.polys.polyerrors.PolynomialError) as err:
        raise ValueError(f"canonical_form: expected a polynomial in sines and cosines of the angles, "
                         f"lengths, rates and parameters, got {expr}: {err}") from None
    return rg.reduce(p).as_expr()


# ------------------------------------------------------------------ entry point
_SYMBOLIC: dict[tuple[Structure, str], Derivation] = {}
_NUMERIC: dict[tuple[Mechanism, str], Derivation] = {}
_FAILED: dict[tuple[Structure, str], float] = {}   # seconds an unfinished derivation ran


def clear_cache() -> None:
    """Forget every derivation (for benchmarks that time a fresh derivation)."""
    _SYMBOLIC.clear()
    _NUMERIC.clear()
    _FAILED.clear()


def parameter_values(mech: Mechanism, symbols: Symbols) -> dict[sp.Symbol, sp.Rational]:
    """Masses, fractions and g as exact Rationals equal to the mechanism's float64 values."""
    return {k: sp.Rational(v) for k, v in symbols.parameter_values(mech).items()}


def _substitute(sym: Derivation, mech: Mechanism) -> Derivation:
    t0 = time.perf_counter()
    f = sym.ring_form
    rg = f.ring
    vals = parameter_values(mech, sym.symbols)
    sub = lambda p: rg.substitute(p, vals)
    form = _RingForm(rg, [sub(e) for e in f.equations],
                     {blk: {name: [[sub(x) for x in row] for row in rows] for name, rows in m.items()}
                      for blk, m in f.matrices.items()}, sub(f.T), sub(f.Pi))
    seconds = dict(sym.seconds)
    out = _from_ring(sym.structure, form, False, sym.engine, seconds, vals)
    seconds["substitute"] = time.perf_counter() - t0
    return out


def derive(mech: Mechanism, symbolic_parameters: bool = False, budget: float = 60.0,
           engine: str = "poly", cache: bool = True) -> Derivation:
    """Lagrange II for ``mech``; cached per structure (and, with numbers, per mechanism).

    ``symbolic_parameters=True`` keeps ``m{i}_{b}``, ``n{i}`` and ``g`` as symbols (zero masses
    of ``mech`` are structural zeros); ``False`` substitutes the mechanism's values as exact
    Rationals. Raises :class:`BudgetExceeded` (with ``skip_reason``) when the derivation does
    not finish within ``budget`` seconds; an unfinished derivation is remembered, and a later
    call with no more time than it already had fails at once. ``cache=False`` derives afresh
    (for timing) and stores nothing.
    """
    if engine not in ENGINES:
        raise ValueError(f"derive: field 'engine': expected one of {', '.join(ENGINES)}, got {engine!r}")
    st = structure_of(mech)
    key = (st, engine)
    if cache and not symbolic_parameters and (mech, engine) in _NUMERIC:
        return _NUMERIC[(mech, engine)]
    with time_budget(budget, f"Lagrange II derivation ({engine})", st.nlinks, st.dim) as dl:
        sym = _SYMBOLIC.get(key) if cache else None
        if sym is None:
            if cache and key in _FAILED and dl.remaining <= _FAILED[key]:
                raise dl.exceeded(note=f"; an earlier attempt ran {_FAILED[key]:.2f} s without finishing")
            t0 = time.perf_counter()
            try:
                sym = _derive_symbolic(st, engine, dl)
            except (BudgetExceeded, BudgetAlarm):  # a cooperative check or the SIGALRM interrupt
                if cache:
                    _FAILED[key] = max(_FAILED.get(key, 0.0), time.perf_counter() - t0)
                raise
            if cache:
                _SYMBOLIC[key] = sym
        if symbolic_parameters:
            return sym
        num = _substitute(sym, mech)
        if cache:
            _NUMERIC[(mech, engine)] = num
        return num
