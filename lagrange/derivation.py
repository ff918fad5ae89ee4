"""Lagrange's equations of the second kind, derived with sympy from the point masses' T and Pi.

This is the suite's independent symbolic check of the paper's matrix method: it never uses the
closed forms (mu, nu, eq. 6). This module builds T and Pi from the geometry and Lagrange II, term
by term, and holds :func:`derive`, the entry point, its result :class:`Derivation`, the time budget
and the caches; beside it:

* :mod:`exo_bench.lagrange.ring`: the polynomial ring it is done in, and the normal form modulo
  ``sin^2 + cos^2 = 1`` (:func:`exo_bench.lagrange.ring.canonical_form`);
* :mod:`exo_bench.lagrange.matrix_form`: the paper's matrices (eqs. 5 and 17) read off the equations
  (:func:`exo_bench.lagrange.matrix_form.extract_matrices`) and written back.

**Engines.** ``engine="poly"`` (the default) does every step in the sparse polynomial ring;
``engine="expr"`` is the textbook route: the same T and Pi as sympy expressions, ``sympy.diff`` and
``sympy.expand``; it gives identical equations about a hundred times slower and exists so that a
benchmark can time the plain computer-algebra derivation the paper timed in Mathematica.

**Parameters and caching.** The symbolic form is derived once per *structure* (dim, parent,
sign and which masses are zero; zero masses are structural zeros) with masses ``m{i}_{b}``,
fractions ``n{i}`` and ``g`` as symbols. ``symbolic_parameters=False`` then substitutes the
mechanism's numbers as **exact sympy Rationals** equal to the float64 values (so the 50-digit
reference of :mod:`exo_bench.lagrange.high_precision` sees exactly the float model).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import cached_property

import sympy as sp
from sympy.polys.rings import PolyElement

from exo_bench.lagrange.budget import BudgetAlarm, BudgetExceeded, Deadline, time_budget
from exo_bench.lagrange.matrix_form import BLOCKS, extract_ring, matrices_expr
from exo_bench.lagrange.ring import TrigRing
from exo_bench.models.machine.memory import BoundedCache
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import Symbols, symbols_for


# Lagrange II from the point masses' T and Pi, built from the geometry alone.


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
    zero_masses = tuple((m0 == 0.0, m1 == 0.0, m2 == 0.0) for m0, m1, m2 in mech.masses)
    return Structure(mech.dim, mech.parent, mech.sign, zero_masses)


@dataclass
class Energies:
    T: PolyElement  # in the ring of exo_bench.lagrange.ring.TrigRing
    Pi: PolyElement


def energies_poly(st: Structure, rg: TrigRing, dl: Deadline) -> Energies:
    """T and Pi of the point masses, positions built down the tree from the geometry."""
    R, S, n, dim = rg.R, rg.S, st.nlinks, st.dim
    dof = dim * n
    g = rg.gen[S.g]
    ends: list[list] = []
    T, Pi = R.zero, R.zero
    for i in range(n):
        p = st.parent[i]
        start = ends[p] if p >= 0 else [R.zero] * dim  # end of the parent, or O
        w = [st.sign[i] * rg.q_l[i] * x for x in rg.unit(i)]  # w_i = s_i l_i u_i
        ends.append([a + b for a, b in zip(start, w)])
        for b, frac in enumerate((R.zero, rg.gen[S.n[i]], R.one)):
            dl.check()
            if st.zero_masses[i][b]:
                continue
            m = rg.gen[S.m[i][b]]
            r = [a + frac * c for a, c in zip(start, w)]  # r_ib = start + n_ib w_i
            v = [sum((rg.d_dq(x, a) * rg.qd[a] for a in range(dof)), R.zero) for x in r]
            T += m * sum((x * x for x in v), R.zero) / 2  # 1/2 m |v|^2
            Pi += m * g * r[-1]  # m g h
    return Energies(rg.reduce(T), Pi)


def lagrange_poly(rg: TrigRing, E: Energies, dof: int, dl: Deadline) -> list:
    """Lagrange II for every coordinate, in the ring."""
    eqs = []
    for a in range(dof):
        dl.check()
        p_a = E.T.diff(rg.qd[a])  # dT/dqd_a
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


def derive_expr(st: Structure, rg: TrigRing, dl: Deadline) -> tuple[Energies, list]:
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
    return Energies(rg.reduce(rg.from_expr(T)), rg.from_expr(Pi)), eqs


ENGINES = ("poly", "expr")


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
    ring_form: RingForm = field(repr=False, kw_only=True)  # internal: the ring elements
    values: dict = field(default_factory=dict, repr=False)  # the substituted parameter values ({} if symbolic)

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
        return sp.Matrix.vstack(*[sp.Matrix.hstack(*[self.matrices[k][c] for c in cols]) for k in BLOCKS[self.dim]])


@dataclass(frozen=True, eq=False)
class RingForm:
    """The ring elements behind a symbolic :class:`Derivation` (numbers are substituted here)."""

    ring: TrigRing
    equations: list
    matrices: dict[str, dict[str, list]]
    T: PolyElement
    Pi: PolyElement


def _derive_symbolic(st: Structure, engine: str, dl: Deadline) -> Derivation:
    S = symbols_for(st.nlinks, st.dim)
    seconds: dict[str, float] = {}
    t0 = time.perf_counter()
    rg = TrigRing(S, st.dim)
    if engine == "poly":
        E = energies_poly(st, rg, dl)
        t1 = time.perf_counter()
        seconds["energies"] = t1 - t0
        eqs = lagrange_poly(rg, E, st.dim * st.nlinks, dl)
        seconds["lagrange"] = time.perf_counter() - t1
    else:
        E, eqs = derive_expr(st, rg, dl)
        seconds["lagrange"] = time.perf_counter() - t0
    t2 = time.perf_counter()
    mats = extract_ring(rg, eqs, dl)
    seconds["matrices"] = time.perf_counter() - t2
    form = RingForm(rg, eqs, mats, E.T, E.Pi)
    out = _from_ring(st, form, True, engine, seconds)
    seconds["total"] = time.perf_counter() - t0
    return out


def _from_ring(
    st: Structure, form: RingForm, symbolic: bool, engine: str, seconds: dict, values: dict | None = None
) -> Derivation:
    """The sympy expressions of a ring form."""
    return Derivation(
        st,
        form.ring.S,
        tuple(e.as_expr() for e in form.equations),
        matrices_expr(form.matrices),
        form.T.as_expr(),
        form.Pi.as_expr(),
        symbolic,
        engine,
        seconds,
        values or {},
        ring_form=form,
    )


# ------------------------------------------------------------------ entry point
# Bounded memos (models/machine/memory.py): a process deriving many mechanisms keeps the latest few. A
# symbolic derivation of a 30-link chain holds gigabytes, so few of each; failures are a float each.
_SYMBOLIC: BoundedCache[tuple[Structure, str], Derivation] = BoundedCache(16)
_NUMERIC: BoundedCache[tuple[Mechanism, str], Derivation] = BoundedCache(16)
_FAILED: BoundedCache[tuple[Structure, str], float] = BoundedCache(256)  # seconds an unfinished derivation ran


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
    form = RingForm(
        rg,
        [sub(e) for e in f.equations],
        {
            blk: {name: [[sub(x) for x in row] for row in rows] for name, rows in m.items()}
            for blk, m in f.matrices.items()
        },
        sub(f.T),
        sub(f.Pi),
    )
    seconds = dict(sym.seconds)
    out = _from_ring(sym.structure, form, False, sym.engine, seconds, vals)
    seconds["substitute"] = time.perf_counter() - t0
    return out


def derive(
    mech: Mechanism, symbolic_parameters: bool = False, budget: float = 60.0, engine: str = "poly", cache: bool = True
) -> Derivation:
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
            t0 = dl.clock()  # the budget's clock (injectable: lagrange.budget.budget_clock)
            try:
                sym = _derive_symbolic(st, engine, dl)
            except (BudgetExceeded, BudgetAlarm):  # a cooperative check or the SIGALRM interrupt
                if cache:
                    _FAILED[key] = max(_FAILED.get(key, 0.0), dl.clock() - t0)
                raise
            if cache:
                _SYMBOLIC[key] = sym
        if symbolic_parameters:
            return sym
        num = _substitute(sym, mech)
        if cache:
            _NUMERIC[(mech, engine)] = num
        return num
