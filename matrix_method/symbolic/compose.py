"""The matrix method in sympy: the explicit equations of motion, composed from the closed forms.

* :func:`planar_matrices`: the matrices of eq. (5) from :mod:`exo_bench.matrix_method.closed_forms.planar`;
* :func:`matrices`: in 3D, those of eq. (17) by the corrected transitions (18) of
  :mod:`exo_bench.matrix_method.closed_forms.transitions` from the planar ones of the same structure;
* :func:`compose_equations`: eq. (5) / (17), the matrices times the rate vectors: the equations
  the paper composes "bypassing Lagrange's equations" (its timing table), equal to
  :func:`exo_bench.lagrange.derive`'s (tested with :func:`exo_bench.lagrange.canonical_form`).

Expressions use the shared symbols of :func:`exo_bench.models.mechanism.symbols.symbols_for`. With
``symbolic_parameters=True`` masses, fractions and ``g`` stay symbols (each coefficient is one
factor, e.g. ``(m2_0 + m2_1 + m2_2 + m1_1*n1**2 + m1_2)*l1**2*ddphi1``); otherwise they are the
mechanism's values as exact Rationals equal to the floats, as :mod:`lagrange` does, so the two
compare exactly. Entries are built directly from the closed forms in a sparse polynomial ring
(:mod:`exo_bench.matrix_method.symbolic.polynomials`), with no simplification pass; ``cos(phi_i - phi_j)`` and
``sin(phi_i - phi_j)`` appear as such (``sympy.expand_trig`` expands them).
"""

from __future__ import annotations

from functools import lru_cache

import sympy as sp

from exo_bench.matrix_method.closed_forms import planar, transitions as spatial
from exo_bench.matrix_method.closed_forms.coefficients import generic_coupling
from exo_bench.matrix_method.symbolic.polynomials import Element, Generators, generators
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import symbols_for

from exo_bench.models.states.equation_form import PLANAR_NAMES, RATES, SPATIAL_NAMES, blocks, matrix_names

#: ``block -> name -> {(i, j): element}``: the elements of every matrix, zeros left out.
Entries = dict[str, dict[str, dict[tuple[int, int], Element]]]
#: ``block -> {i: p_i}``: the gravity vector of every block.
Gravity = dict[str, dict[int, Element]]


def planar_entries(G: Generators, c, pairs, straight: bool = False) -> Entries:
    """Eq. (5): ``block -> name -> {(i, j): element}`` over ``pairs`` (those with ``c_ij != 0``),
    ring elements. ``straight``: the straightened model (``phi_i = phi_j``: ``C = 1, S = 0``)."""
    out: Entries = {b: {name: {} for name in PLANAR_NAMES} for b in ("phi", "l")}
    for i, j in pairs:
        C, Sn = (1, 0) if straight else (G.C(i, j), G.S(i, j))
        li, lj = G["l", i], G["l", j]
        for block, fns in planar.PAIRS.items():
            for name, f in fns.items():
                out[block][name][(i, j)] = f(c[i][j], li, lj, C, Sn)
    return out


def planar_gravity(G: Generators, nu_s, links) -> Gravity:
    """Eq. (5): ``block -> {i: p_i}`` for the links ``links``."""
    return {
        block: {i: f(nu_s[i], G["l", i], G["cphi", i], G["sphi", i]) for i in links}
        for block, f in planar.GRAVITY.items()
    }


def spatial_entries(G: Generators, now: Entries, straight: Entries, pairs) -> Entries:
    """Eq. (18), corrected: the 3D elements of ``pairs`` from the planar ones (``now``) and the
    straightened planar ones (the quotients), ``block -> name -> {(i, j): element}``."""
    out: Entries = {b: {name: {} for name in SPATIAL_NAMES} for b in ("phi", "psi", "l")}
    for i, j in pairs:
        pick = lambda src: {b: {name: src[b][name][(i, j)] for name in PLANAR_NAMES} for b in src}
        t = spatial.transition_inputs(
            pick(now), pick(straight), G["l", i], G["l", j], G["cpsi", i], G["spsi", i], G["cpsi", j], G["spsi", j]
        )
        for block, fns in spatial.PAIRS.items():
            for name, f in fns.items():
                if (block, name) != ("l", "D"):
                    out[block][name][(i, j)] = f(t)
    for i, j in pairs:
        if (j, i) in out["phi"]["H"]:
            out["l"]["D"][(i, j)] = spatial.d_l(out["phi"]["H"][(j, i)])  # D_l = -(H_phi)^T
    return out


def spatial_gravity(G: Generators, nu_s, links) -> Gravity:
    return {
        block: {i: f(nu_s[i], G["l", i], G["cpsi", i], G["spsi", i]) for i in links}
        for block, f in spatial.GRAVITY.items()
    }


def _ring_form(mech: Mechanism, G: Generators) -> tuple[Entries, Gravity]:
    """Every matrix of the model as ring elements: ``(entries, gravity)``."""
    c, nu_s = generic_coupling(mech, G.parameters(mech), 0)
    n = mech.nlinks
    pairs = [(i, j) for i in range(n) for j in range(n) if c[i][j] != 0]
    now = planar_entries(G, c, pairs)
    if mech.dim == 2:
        return now, planar_gravity(G, nu_s, range(n))
    straight = planar_entries(G, c, pairs, straight=True)
    return spatial_entries(G, now, straight, pairs), spatial_gravity(G, nu_s, range(n))


def to_matrices(G: Generators, n: int, entries: Entries, gravity: Gravity) -> dict[str, dict[str, sp.Matrix]]:
    """Ring entries as ``block -> name -> sympy Matrix`` (``P`` is ``(n, 1)``, without ``g``)."""
    out: dict[str, dict[str, sp.Matrix]] = {}
    for block, mats in entries.items():
        out[block] = {}
        for name, e in mats.items():
            M = sp.zeros(n, n)
            for (i, j), v in e.items():
                M[i, j] = G.expr(v)
            out[block][name] = M
        out[block]["P"] = sp.Matrix(n, 1, [G.expr(gravity[block][i]) for i in range(n)])
    return out


def planar_matrices(mech: Mechanism, symbolic_parameters: bool = False) -> dict[str, dict[str, sp.Matrix]]:
    """Eq. (5): the planar matrices of the model of the same structure (angles ``phi``, lengths
    ``l``), ``block -> name -> Matrix`` (``P`` is ``(n, 1)`` and excludes ``g``)."""
    return matrices(mech.replace(dim=2), symbolic_parameters)


def matrices(mech: Mechanism, symbolic_parameters: bool = False) -> dict[str, dict[str, sp.Matrix]]:
    """Every matrix of eq. (5) (2D) or (17) (3D), in the convention of :mod:`lagrange`."""
    G = generators(mech.nlinks, mech.dim, symbolic_parameters)
    return to_matrices(G, mech.nlinks, *_ring_form(mech, G))


def rate_vectors(G: Generators, dim: int, n: int) -> dict[str, list]:
    """The factor multiplying element ``(i, j)`` of each matrix in eq. (5)/(17), by j, from the rate
    table :data:`exo_bench.models.states.equation_form.RATES` (second derivatives, or a factor times a product of rates)."""

    def rate(name: str, j: int):
        factor, r = RATES[name]
        if len(r) == 1:
            return G["dd" + r[0], j]
        x = G["d" + r[0], j] ** 2 if r[0] == r[1] else G["d" + r[0], j] * G["d" + r[1], j]
        return x if factor == 1 else int(factor) * x  # an integer keeps the ring exact

    return {name: [rate(name, j) for j in range(n)] for name in matrix_names(dim)}


def equations_from_entries(G: Generators, mech: Mechanism, entries: Entries, gravity: Gravity) -> tuple[sp.Expr, ...]:
    """Eq. (5) / (17): row i of block k is ``sum_X sum_j X_ij x^X_j + g P_i``."""
    n = mech.nlinks
    g = G.gravity(mech)
    rates = rate_vectors(G, mech.dim, n)
    out: list[sp.Expr] = []
    for block in blocks(mech.dim):
        rows = [g * gravity[block][i] for i in range(n)]
        for name, e in entries[block].items():
            x = rates[name]
            for (i, j), v in e.items():
                rows[i] = rows[i] + v * x[j]
        out.extend(G.expr(r) for r in rows)
    return tuple(out)


def compose_equations(mech: Mechanism, symbolic_parameters: bool = False) -> tuple[sp.Expr, ...]:
    """Eq. (5) / (17): the equations of motion ``tau`` in block order, composed by the matrix method.

    The closed-form elements (zero across branches, skipped), multiplied by the rate vectors and
    summed. No simplification pass.
    """
    G = generators(mech.nlinks, mech.dim, symbolic_parameters)
    return equations_from_entries(G, mech, *_ring_form(mech, G))


@lru_cache(maxsize=32)
def lambdified(mech: Mechanism, compose=None):
    """The composed equations as one numpy function ``f(q..., qd..., qdd...)`` (cached).
    ``compose``: the composer (default :func:`compose_equations`; the recurrence's
    ``matrix_method.recurrence.compose_equations`` gives the same equations)."""
    compose = compose or compose_equations
    S = symbols_for(mech.nlinks, mech.dim)
    return sp.lambdify(list(S.q + S.qd + S.qdd), list(compose(mech)), modules="numpy", cse=True)
