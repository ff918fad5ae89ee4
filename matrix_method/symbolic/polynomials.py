"""Fast construction of the symbolic equations: closed-form elements as small sparse polynomials.

Composing the equations is the paper's timed step (its table: Lagrange vs matrix method). Built
with sympy's operators, every product and sum re-canonicalises its arguments, which costs far more
than the arithmetic. Here every symbolic quantity of the closed forms is a :class:`Poly`: a dict
from a monomial (a sorted tuple of generator indices) to an exact coefficient. The generators are
the state symbols and the sines and cosines the closed forms use (``l_i``, rates, accelerations,
``cos/sin phi_i``, ``cos/sin psi_i``, ``cos/sin(phi_i - phi_j)``); coefficients are
:class:`fractions.Fraction` (numeric parameters, the exact values of the floats) or, with symbolic
parameters, :class:`Poly` in the masses ``m_ib``, fractions ``n_i`` and ``g``. The element
functions of :mod:`exo_bench.matrix_method.closed_forms.planar` and :mod:`exo_bench.matrix_method.closed_forms.transitions` run unchanged on them
and like terms merge as they are added.

:meth:`Generators.expr` turns a Poly into the sympy expression that sympy's own constructors give
for the same terms, without re-deriving it: factors and terms are ordered with :func:`order_key`,
a key that reproduces ``Basic.compare`` (the comparison ``Add`` and ``Mul`` sort their arguments
with), and joined with ``Mul._from_args`` / ``Add._from_args``. A parameter coefficient with
several terms stays one factor, ``rational * (m... + ...)``. ``Add(*e.args) == e`` (tested).
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache, cache
from math import gcd

import sympy as sp
from sympy.core.add import Add
from sympy.core.basic import Basic, ordering_of_classes
from sympy.core.mul import Mul

from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import symbols_for


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
