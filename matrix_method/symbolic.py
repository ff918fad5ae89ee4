"""The matrix method in sympy: the explicit equations of motion, composed from the closed forms, the
sparse polynomials they are built in, and the mass coefficients as sympy expressions.

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
(:class:`Poly`, below: closed-form elements as small sparse polynomials, faster than sympy's operators),
with no simplification pass; ``cos(phi_i - phi_j)`` and
``sin(phi_i - phi_j)`` appear as such (``sympy.expand_trig`` expands them).
"""

from __future__ import annotations

from fractions import Fraction
from functools import cache, lru_cache
from math import gcd

import sympy as sp
from sympy.core.add import Add
from sympy.core.basic import Basic, ordering_of_classes
from sympy.core.mul import Mul

from exo_bench.matrix_method.closed_forms import planar, transitions as spatial
from exo_bench.matrix_method.closed_forms.coefficients import generic_aggregates, generic_coupling
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import Symbols, symbols_for
from exo_bench.models.states.states import PLANAR_NAMES, RATES, SPATIAL_NAMES, blocks, matrix_names


# Fast construction of the symbolic equations: closed-form elements as small sparse polynomials.


# ------------------------------------------------------------------ sympy's canonical order
@cache
def _class_key(cls: type) -> tuple:
    """The order of ``sympy.core.basic._cmp_name``: listed classes by position, then by name."""
    try:
        return (ordering_of_classes.index(cls.__name__), "")
    except ValueError:
        return (len(ordering_of_classes) + 1, cls.__name__)


_KEYS: dict = {}


def order_key(x) -> tuple:
    """A sort key equal in effect to ``functools.cmp_to_key(Basic.compare)``: class, then length
    of the hashable content, then the content element by element."""
    if isinstance(x, Basic):
        k = _KEYS.get(x)
        if k is None:
            content = x._hashable_content()
            cls: type = type(x)
            k = (_class_key(cls), len(content), tuple(order_key(e) for e in content))
            if len(_KEYS) < 200_000:
                _KEYS[x] = k
        return k
    if isinstance(x, frozenset):
        return order_key(Basic(*x))
    return (x,)


def _mul(number, factors) -> sp.Expr:
    """``number * prod(factors)`` as sympy's canonical Mul (factors: expressions, no numbers)."""
    factors.sort(key=order_key)
    args = tuple(factors)
    if not args:
        return number
    if len(args) == 1 and args[0].is_Add and number != 1:
        return Mul(number, args[0])  # sympy distributes a number over a lone sum
    if number == 1:
        return args[0] if len(args) == 1 else Mul._from_args(args, is_commutative=True)
    return Mul._from_args((number,) + args, is_commutative=True)


def _add(terms) -> sp.Expr:
    if not terms:
        return sp.S.Zero
    if len(terms) == 1:
        return terms[0]
    flat: list[sp.Expr] = []
    for t in terms:
        flat.extend(t.args if t.is_Add else (t,))
    numbers = [t for t in flat if t.is_Number]
    rest = sorted((t for t in flat if not t.is_Number), key=order_key)
    if len(numbers) > 1:
        numbers = [sp.Add(*numbers)]
    if numbers and numbers[0] == 0:
        numbers = []
    if not numbers and len(rest) == 1:
        return rest[0]
    return Add._from_args(tuple(numbers + rest))


def _rational(c) -> sp.Rational:
    return sp.Integer(c) if isinstance(c, int) else sp.Rational(c.numerator, c.denominator)


# ------------------------------------------------------------------ the polynomials
def _accumulate(terms: dict, monomial, coefficient) -> None:
    """Add ``coefficient * monomial`` to ``terms`` in place, dropping a term that cancels."""
    total = terms.get(monomial, 0) + coefficient
    if total == 0:
        terms.pop(monomial, None)
    else:
        terms[monomial] = total


class Poly:
    """A sparse polynomial over the state generators: ``{monomial: coefficient}``, monomial a
    sorted tuple of generator indices (repeated for powers). Supports ``+ - *``, ``**`` by small
    integers and comparison with 0. Numbers (int, Fraction) and :class:`Coefficient` (parameter
    polynomials, one level down) act as constants."""

    __slots__ = ("terms",)
    level = 1

    def __init__(self, terms: dict):
        self.terms = terms

    def _lift(self, x):
        if isinstance(x, Poly) and x.level == self.level:
            return x
        return type(self)({(): x}) if x != 0 else type(self)({})

    def __add__(self, other):
        if isinstance(other, Poly) and other.level > self.level:
            return other + self
        other = self._lift(other)
        out = dict(self.terms)
        for m, c in other.terms.items():
            _accumulate(out, m, c)
        return type(self)(out)

    __radd__ = __add__

    def __neg__(self):
        return type(self)({m: -c for m, c in self.terms.items()})

    def __sub__(self, other):
        return self + (-other)

    def __rsub__(self, other):
        return (-self) + other

    def __mul__(self, other):
        if isinstance(other, Poly) and other.level > self.level:
            return other * self
        if not (isinstance(other, Poly) and other.level == self.level):
            if other == 0:
                return type(self)({})
            if other == 1:
                return self
            return type(self)({m: c * other for m, c in self.terms.items()})
        out: dict = {}
        for m1, c1 in self.terms.items():
            for m2, c2 in other.terms.items():
                _accumulate(out, tuple(sorted(m1 + m2)) if m1 and m2 else (m1 or m2), c1 * c2)
        return type(self)(out)

    __rmul__ = __mul__

    def __pow__(self, k: int):
        out = type(self)({(): 1})
        for _ in range(k):
            out = out * self
        return out

    def __eq__(self, other):
        if isinstance(other, Poly) and other.level == self.level:
            return self.terms == other.terms
        return self.terms == ({(): other} if other != 0 else {})

    def __ne__(self, other):
        return not self == other

    # Unhashable (mutable terms): defining __eq__ without __hash__ sets __hash__ to None.


class Coefficient(Poly):
    """A polynomial in the parameters (masses, fractions, g); its coefficients are integers."""

    __slots__ = ()
    level = 0


#: An element of the closed forms in this arithmetic: a polynomial, or an exact constant.
Element = Poly | Fraction | int


class _Basis:
    """Generator objects by index, with cached powers."""

    def __init__(self, objects):
        self.objects = objects
        self._pow: dict[tuple[int, int], sp.Expr] = {}

    def factors(self, monom) -> list:
        out, k = [], 0
        while k < len(monom):
            g, e = monom[k], 1
            while k + e < len(monom) and monom[k + e] == g:
                e += 1
            k += e
            f = self._pow.get((g, e))
            if f is None:
                f = self._pow[(g, e)] = self.objects[g] if e == 1 else sp.Pow(self.objects[g], e)
            out.append(f)
        return out


class Generators:
    """The generators of one model size ``(nlinks, dim)`` and the emitter to sympy."""

    def __init__(self, nlinks: int, dim: int, symbolic_parameters: bool):
        S = symbols_for(nlinks, dim)
        self.symbols = S
        self.symbolic_parameters = symbolic_parameters
        n = nlinks
        names: list[tuple[tuple, sp.Expr]] = []
        add = lambda key, e: names.append((key, e))
        for i in range(n):
            add(("l", i), S.l[i])
            add(("cphi", i), sp.cos(S.phi[i]))
            add(("sphi", i), sp.sin(S.phi[i]))
            for kind, sym in (("dphi", S.dphi), ("ddphi", S.ddphi), ("dl", S.dl), ("ddl", S.ddl)):
                add((kind, i), sym[i])
            if dim == 3:
                add(("cpsi", i), sp.cos(S.psi[i]))
                add(("spsi", i), sp.sin(S.psi[i]))
                add(("dpsi", i), S.dpsi[i])
                add(("ddpsi", i), S.ddpsi[i])
        # cos and sin of (phi_i - phi_j), i < j, as sympy writes them (sin may carry a sign)
        self._pair_sign: dict[tuple[int, int], int] = {}
        for i in range(n):
            for j in range(i + 1, n):
                d = S.phi[i] - S.phi[j]
                add(("C", i, j), sp.cos(d))
                s = sp.sin(d)
                sign = 1
                if isinstance(s, Mul):  # -sin(phi_j - phi_i)
                    sign, s = -1, -s
                self._pair_sign[(i, j)] = sign
                add(("S", i, j), s)
        self._basis = _Basis([e for _, e in names])
        self.gen = {k: Poly({(idx,): 1}) for idx, (k, _) in enumerate(names)}
        if symbolic_parameters:
            pk = [("m", i, b) for i in range(n) for b in range(3)] + [("n", i) for i in range(n)] + [("g",)]
            po = [S.m[i][b] for i in range(n) for b in range(3)] + list(S.n) + [S.g]
            self._param_basis = _Basis(po)
            self._param = {k: Coefficient({(idx,): 1}) for idx, k in enumerate(pk)}  # integer coefficients
        self._coefficients: dict = {}

    # ------------------------------------------------------------ elements
    def __getitem__(self, key) -> Poly:
        return self.gen[key]

    def C(self, i: int, j: int):
        """``cos(phi_i - phi_j)``; 1 on the diagonal."""
        if i == j:
            return 1
        return self.gen[("C", min(i, j), max(i, j))]

    def S(self, i: int, j: int):
        """``sin(phi_i - phi_j)``; 0 on the diagonal."""
        if i == j:
            return 0
        a, b = min(i, j), max(i, j)
        sign = self._pair_sign[(a, b)] * (1 if i < j else -1)
        g = self.gen[("S", a, b)]
        return g if sign == 1 else -g

    @staticmethod
    def number(x):
        """An exact constant: a float is taken at its exact binary value."""
        return Fraction(x)

    def parameter(self, key):
        """A mass ``("m", i, b)``, fraction ``("n", i)`` or ``("g",)`` (symbolic parameters only)."""
        return self._param[key]

    def parameters(self, mech: Mechanism):
        """Per link ``(m0, m1, m2, n)``: parameter polynomials, or exact numbers."""
        if self.symbolic_parameters:
            return [
                tuple(self._param[("m", i, b)] for b in range(3)) + (self._param[("n", i)],) for i in range(mech.nlinks)
            ]
        return [tuple(Fraction(x) for x in (*mech.masses[i], mech.n[i])) for i in range(mech.nlinks)]

    def gravity(self, mech: Mechanism):
        return self._param[("g",)] if self.symbolic_parameters else Fraction(mech.g)

    # ------------------------------------------------------------ emission
    def _coefficient(self, c):
        """``(number, factors)`` of a coefficient: a rational, or a parameter polynomial with its
        rational content taken out (one term: its factors join the term's; several: one sum)."""
        if not isinstance(c, Coefficient):
            return _rational(c), []
        key = tuple(sorted(c.terms.items()))
        hit = self._coefficients.get(key)
        if hit is None:
            if len(c.terms) == 1:
                ((m, k),) = c.terms.items()
                hit = (_rational(k), self._param_basis.factors(m))
            else:
                ks = [Fraction(k) for k in c.terms.values()]
                num, den = 0, 1
                for k in ks:
                    num = gcd(num, k.numerator)
                    den = den * k.denominator // gcd(den, k.denominator)
                content = Fraction(num, den)
                add = _add(
                    [_mul(_rational(Fraction(k) / content), self._param_basis.factors(m)) for m, k in c.terms.items()]
                )
                hit = (_rational(content), [add])
            self._coefficients[key] = hit
        return hit[0], list(hit[1])

    def expr(self, p) -> sp.Expr:
        """A Poly (or a plain number) as sympy's canonical expression."""
        if isinstance(p, Coefficient):
            p = Poly({(): p} if p != 0 else {})  # a constant element, e.g. 2D lambda^l_ii
        if not isinstance(p, Poly):
            return _rational(p) if isinstance(p, (int, Fraction)) else sp.sympify(p)
        terms = []
        for monom, coeff in p.terms.items():
            number, factors = self._coefficient(coeff)
            if factors and monom:
                terms.append(_mul(number, factors + self._basis.factors(monom)))
            elif monom:
                terms.append(_mul(number, self._basis.factors(monom)))
            else:
                terms.append(_mul(number, factors))
        return _add(terms)


@lru_cache(maxsize=64)
def generators(nlinks: int, dim: int, symbolic_parameters: bool) -> Generators:
    """The generators of a model size (cached, like :func:`exo_bench.models.mechanism.symbols.symbols_for`)."""
    return Generators(nlinks, dim, symbolic_parameters)


def clear_caches() -> None:
    """Forget every cached generator table and sort key (and sympy's own cache), so that the next
    composition is timed cold, as in a fresh process."""
    from sympy.core.cache import clear_cache

    generators.cache_clear()
    _KEYS.clear()
    _class_key.cache_clear()
    clear_cache()


# The equations composed: every matrix of eq. (5)/(17) and the equations, from the closed forms.

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
    table :data:`exo_bench.models.states.states.RATES` (second derivatives, or a factor times a product of rates)."""

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


# The mass coefficients of :mod:`exo_bench.matrix_method.closed_forms.coefficients` as sympy expressions.


def parameters(mech: Mechanism, S: Symbols, symbolic_parameters: bool):
    """Per link ``(m0, m1, m2, n)``: the shared symbols, or exact Rationals equal to the floats
    (so that expressions compare exactly with :func:`exo_bench.lagrange.derive`'s, which does the same)."""
    if symbolic_parameters:
        return [(*S.m[i], S.n[i]) for i in range(mech.nlinks)]
    return [tuple(sp.Rational(x) for x in (*mech.masses[i], mech.n[i])) for i in range(mech.nlinks)]


def symbolic_aggregates(mech: Mechanism, S: Symbols, symbolic_parameters: bool):
    """``zeta, eta, theta`` per link as sympy expressions in the mass symbols, or exact numbers."""
    return generic_aggregates(parameters(mech, S, symbolic_parameters))


def symbolic_coupling(mech: Mechanism, S: Symbols, symbolic_parameters: bool):
    """``(c, nu_s)`` as sympy expressions (mass symbols or exact numbers)."""
    return generic_coupling(mech, parameters(mech, S, symbolic_parameters), sp.S.Zero)
