"""The mass coefficients of the closed forms: the aggregates of eq. (6) with the branch signs.

The aggregates ``zeta, eta, theta`` of eq. (6), the descendant masses ``Theta`` and the mass
coupling ``mu_ij`` / gravity coefficients ``nu_k`` of ``T = 1/2 sum_ij mu_ij w_i' . w_j'`` and
``Pi = g sum_k nu_k (w_k . up)`` are defined once, in :mod:`exo_bench.models.aggregates` (derivation there).
Every matrix element of eqs. (5) and (17) is ``c_ij = mu_ij s_i s_j`` times a geometric factor of
links i and j (:mod:`exo_bench.matrix_method.closed_forms.planar`), so the sign products of a branched model ("reversed
links contribute sign products") live in ``c`` alone; this module adds them.

Each function exists in a numeric form (floats from the mechanism) and a symbolic form
(expressions in the shared mass symbols of :func:`exo_bench.models.symbols.symbols_for`), both built on
:func:`exo_bench.models.aggregates.aggregates` and :func:`exo_bench.models.aggregates.coupling_entries`.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from exo_bench.models.aggregates import aggregates, coupling, coupling_entries, gravity_coupling, link_aggregates
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.symbols import Symbols


# ----------------------------------------------------------------- numeric
@lru_cache(maxsize=256)
def signed_coupling(mech: Mechanism) -> np.ndarray:
    """``c_ij = mu_ij s_i s_j``, the coefficient every closed-form element carries, ``(n, n)``."""
    s = mech.sign_array
    c = coupling(mech) * s[:, None] * s[None, :]
    c.flags.writeable = False
    return c


@lru_cache(maxsize=256)
def signed_gravity(mech: Mechanism) -> np.ndarray:
    """``nu_i s_i`` with ``nu_i = eta_i + Theta(i)``: the coefficient of the gravity vectors ``P``."""
    out = gravity_coupling(mech) * mech.sign_array
    out.flags.writeable = False
    return out


def recurrence_increments(mech: Mechanism, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (25) generalised to trees: what adding link ``k`` does to the coefficients.

    Returns ``(idx, dc, dnu_s)``: the links concerned (the ancestors of k, then k itself), the
    increment of ``c`` on ``idx x idx`` and the increment of ``nu s`` on ``idx``.
    ``theta_k s_i s_j`` on ancestor pairs (k adds to Theta of each ancestor), ``eta_k s_i s_k`` on the
    new row and column, ``zeta_k`` in the corner; ``theta_k s_i`` and ``eta_k s_k`` for gravity.
    """
    zeta, eta, theta = link_aggregates(mech)
    idx = np.array(sorted(mech.ancestors[k]) + [k], dtype=int)
    s = mech.sign_array[idx]
    m = len(idx)
    dc = theta[k] * np.outer(s, s)              # First term: old block, ancestors only
    dc[-1, :] = dc[:, -1] = eta[k] * s * s[-1]  # Second term: the new row and column
    dc[-1, -1] = zeta[k]                        # Third term: the corner
    dnu = np.full(m, theta[k]) * s
    dnu[-1] = eta[k] * s[-1]
    return idx, dc, dnu


# ---------------------------------------------------------------- symbolic
def _parameters(mech: Mechanism, S: Symbols, symbolic_parameters: bool):
    """Per link ``(m0, m1, m2, n)``: the shared symbols, or exact Rationals equal to the floats
    (so that expressions compare exactly with :func:`exo_bench.lagrange.derive`'s, which does the same)."""
    if symbolic_parameters:
        return [(*S.m[i], S.n[i]) for i in range(mech.nlinks)]
    return [tuple(sp.Rational(x) for x in (*mech.masses[i], mech.n[i])) for i in range(mech.nlinks)]


def generic_aggregates(params):
    """Eq. (6), definitions, in any arithmetic (sympy, ring elements): ``zeta, eta, theta`` per link
    from ``params = [(m0, m1, m2, n), ...]`` (:func:`exo_bench.models.aggregates.aggregates`)."""
    per_link = [aggregates(*p) for p in params]
    return [a[0] for a in per_link], [a[1] for a in per_link], [a[2] for a in per_link]


def symbolic_aggregates(mech: Mechanism, S: Symbols, symbolic_parameters: bool):
    """``zeta, eta, theta`` per link as sympy expressions in the mass symbols, or exact numbers."""
    return generic_aggregates(_parameters(mech, S, symbolic_parameters))


def generic_coupling(mech: Mechanism, params, zero=0):
    """``(c, nu_s)`` in any arithmetic: nested lists ``c_ij = mu_ij s_i s_j`` (``zero`` for links on
    different branches) and ``nu_i s_i``; the generic twin of :func:`signed_coupling`, built on
    :func:`exo_bench.models.aggregates.coupling_entries`."""
    return signed_coupling_entries(mech, *generic_aggregates(params), zero=zero)


def signed_coupling_entries(mech: Mechanism, zeta, eta, theta, zero=0):
    """``(c, nu_s)`` from the per-link aggregates of eq. (6), in any arithmetic (symbols for the
    aggregates themselves: the LaTeX export): the branch signs added to
    :func:`exo_bench.models.aggregates.coupling_entries`."""
    n = mech.nlinks
    mu, nu = coupling_entries(mech, zeta, eta, theta, zero=zero)
    s = mech.sign
    related = mech.ancestor_or_self
    c = [[(s[i] * s[j]) * mu[i][j] if i != j and (related[i, j] or related[j, i]) else mu[i][j]
          for j in range(n)] for i in range(n)]          # the diagonal has s_i^2 = 1, unrelated links zero
    return c, [s[k] * nu[k] for k in range(n)]


def symbolic_coupling(mech: Mechanism, S: Symbols, symbolic_parameters: bool):
    """``(c, nu_s)`` as sympy expressions (mass symbols or exact numbers)."""
    return generic_coupling(mech, _parameters(mech, S, symbolic_parameters), sp.S.Zero)


def generic_recurrence_increments(mech: Mechanism, params, k: int):
    """The generic twin of :func:`recurrence_increments`: ``(idx, dc, dnu_s)`` as nested lists."""
    zeta, eta, theta = generic_aggregates(params)
    idx = sorted(mech.ancestors[k]) + [k]
    s = [mech.sign[i] for i in idx]
    m = len(idx)
    dc = [[(s[a] * s[b]) * theta[k] for b in range(m)] for a in range(m)]   # First term: ancestors
    for a in range(m):
        dc[a][m - 1] = dc[m - 1][a] = (s[a] * s[m - 1]) * eta[k]           # Second term: new row/column
    dc[m - 1][m - 1] = zeta[k]                                             # Third term: the corner
    dnu = [s[a] * theta[k] for a in range(m - 1)] + [s[m - 1] * eta[k]]
    return idx, dc, dnu
