"""The mass coefficients of :mod:`exo_bench.matrix_method.closed_forms.coefficients` as sympy expressions.

The formulas are those of ``coefficients`` (eq. (6) and the branch signs, written once in any
arithmetic); this module only supplies their sympy inputs, the shared mass symbols of
:func:`exo_bench.models.mechanism.symbols.symbols_for` or exact Rationals of the mechanism's floats. Kept apart
so that the numeric path (the kernels' coefficients) never imports sympy.
"""

from __future__ import annotations

import sympy as sp

from exo_bench.matrix_method.closed_forms.coefficients import generic_aggregates, generic_coupling
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import Symbols


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
