"""The polynomial ring of the Lagrange derivation and its normal form modulo ``sin^2 + cos^2 = 1``.

The ring (:func:`sympy.polys.rings.ring` over the rationals) has as generators ``sin``/``cos`` of
the angles, the lengths, rates, accelerations, masses, fractions and ``g``; ``d/dphi`` acts by the
chain rule ``d sin(phi) = cos(phi) dphi``, ``d cos(phi) = -sin(phi) dphi``.

**Normal form.** Results are reduced modulo ``sin^2 + cos^2 = 1`` by ``cos(x)^2 -> 1 - sin(x)^2``
(every ``cos`` appears at most to the first power). This normal form is canonical, so two
polynomial expressions in sines and cosines are equal exactly when their normal forms are;
:func:`canonical_form` brings any expression (e.g. with ``cos(phi_i - phi_j)``) to it.
"""

from __future__ import annotations

import sympy as sp
from sympy import QQ
from sympy.polys.rings import ring

from exo_bench.models.mechanism.symbols import Symbols


class TrigRing:
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
            return p.diff(s) * c - p.diff(c) * s  # d sin = cos, d cos = -sin
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
            for k, (_s, c) in enumerate(self.trig_index):
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
            exps = list(monom)
            for k, v in vals:
                if exps[k]:
                    coeff = coeff * v ** exps[k]
                    exps[k] = 0
            if coeff:
                m = tuple(exps)
                out[m] = out.get(m, 0) + coeff
        return self.R.from_dict({m: c for m, c in out.items() if c})

    def from_expr(self, expr: sp.Expr):
        """An expression polynomial in the generators (after ``expand``) as a ring element."""
        return self.R.from_expr(sp.expand(expr))


def canonical_form(expr: sp.Expr, symbols: Symbols) -> sp.Expr:
    """The normal form of an expression polynomial in sines and cosines of the angles (after
    ``expand_trig``, so ``cos(phi1 - phi2)`` is allowed): expanded, every ``cos^2`` replaced by
    ``1 - sin^2``. Two such expressions are equal exactly when their normal forms are."""
    dim = 3 if symbols.psi else 2
    e = sp.expand(sp.expand_trig(sp.sympify(expr)))
    angles = set(symbols.phi) | set(symbols.psi)
    known = set(TrigRing(symbols, dim).index)
    # Symbols outside the shared set (a caller's own parameters) become extra generators.
    extra = tuple(sorted(e.free_symbols - known - angles, key=str))
    rg = TrigRing(symbols, dim, extra)
    try:
        p = rg.R.from_expr(e)
    except (ValueError, sp.polys.polyerrors.PolynomialError) as err:
        raise ValueError(
            f"canonical_form: expected a polynomial in sines and cosines of the angles, "
            f"lengths, rates and parameters, got {expr}: {err}"
        ) from None
    return rg.reduce(p).as_expr()
