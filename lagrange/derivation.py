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

Modules: :mod:`lagrange.structure` (inputs and result), :mod:`lagrange.ring` (the polynomial
ring), :mod:`lagrange.engines` (T, Pi and Lagrange II), :mod:`lagrange.matrix_form` (the
matrices); this module is the entry point, :func:`derive`, with its cache.
"""

from __future__ import annotations

import time


import sympy as sp

from exo_bench.lagrange.budget import BudgetAlarm
from exo_bench.lagrange.budget import BudgetExceeded
from exo_bench.lagrange.budget import Deadline
from exo_bench.lagrange.budget import time_budget
from exo_bench.lagrange.engines import _derive_expr, _energies_poly, _lagrange_poly
from exo_bench.lagrange.matrix_form import _extract_ring, _matrices_expr
from exo_bench.lagrange.ring import _Ring, _RingForm
from exo_bench.lagrange.structure import Derivation, ENGINES, Structure, structure_of
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.symbols import Symbols
from exo_bench.models.symbols import symbols_for


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

