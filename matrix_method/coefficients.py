"""The mass coefficients of the closed forms: the tree generalisation of the sums of eq. (6).

Derivation (checked against Lagrange's equations and Pinocchio by the tests). Write
``w_i = s_i l_i u_i`` for the vector from the start of rod ``i`` to its end (``s_i = sign[i]``).
Point mass ``beta`` of link ``i`` sits at ``r_ib = sum_{a in anc(i)} w_a + n_ib w_i``, so

    T = 1/2 sum_ij mu_ij  d/dt(w_i) . d/dt(w_j),      Pi = g sum_k nu_k (w_k . up)

where, with the per-link aggregates of eq. (6)
``zeta_i = sum_b m_ib n_ib^2``, ``eta_i = sum_b m_ib n_ib``, ``theta_i = sum_b m_ib`` and
``Theta(k) = sum of theta over the strict descendants of k``:

* ``mu_ii = zeta_i + Theta(i)``                      (every descendant mass moves with w_i);
* ``mu_ij = eta_k + Theta(k)`` if ``i`` and ``j`` are related (one is an ancestor of the other)
  and ``k`` is the deeper of the two (the masses that ride on both rods: link k's own, at
  fractions n_kb, and every descendant of k, at fraction 1);
* ``mu_ij = 0`` for links on different branches (no mass rides on both);
* ``nu_k = eta_k + Theta(k)``.

For a chain, ``Theta(k) = sum_{m=k+1..n} theta_m`` and ``mu`` is exactly the bracket of eq. (6).
Every matrix element of eqs. (5) and (17) is ``c_ij = mu_ij s_i s_j`` times a geometric factor of
links i and j (:mod:`matrix_method.planar`), so the sign products of a branched model ("reversed
links contribute sign products") live in ``c`` alone.

Each function exists in a numeric form (floats from the mechanism) and a symbolic form
(expressions in the shared mass symbols of :func:`models.symbols.symbols_for`).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from exo_bench.models.mechanism import Mechanism
from exo_bench.models.symbols import Symbols


# ----------------------------------------------------------------- numeric
def link_aggregates(mech: Mechanism) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (6), definitions: ``zeta_i, eta_i, theta_i`` of every link, each ``(n,)``."""
    m, f = mech.mass_array, mech.fractions
    return (m * f**2).sum(1), (m * f).sum(1), m.sum(1)


def descendant_mass(mech: Mechanism) -> np.ndarray:
    """Eq. (6), the sum ``sum_{k=j+1..n} theta_k`` on a tree: ``Theta(k)``, the total mass of the
    strict descendants of each link, ``(n,)``."""
    _, _, theta = link_aggregates(mech)
    out = np.zeros(mech.nlinks)
    for k in range(mech.nlinks):
        for a in mech.ancestors[k]:
            out[a] += theta[k]
    return out


@lru_cache(maxsize=256)
def coupling(mech: Mechanism) -> np.ndarray:
    """Eq. (6) generalised to trees: the symmetric ``(n, n)`` mass coupling ``mu_ij``.

    ``mu_ii = zeta_i + Theta(i)``; ``mu_ij = eta_k + Theta(k)`` for related links (k the deeper);
    0 for links on different branches. Read-only (cached per mechanism).
    """
    zeta, eta, _ = link_aggregates(mech)
    Theta = descendant_mass(mech)
    n = mech.nlinks
    mu = np.zeros((n, n))
    for k in range(n):
        mu[k, k] = zeta[k] + Theta[k]           # First term: the link with itself
        for a in mech.ancestors[k]:             # Second term: k with each ancestor, k deeper
            mu[a, k] = mu[k, a] = eta[k] + Theta[k]
    mu.flags.writeable = False
    return mu


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
    _, eta, _ = link_aggregates(mech)
    out = (eta + descendant_mass(mech)) * mech.sign_array
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
    (so that expressions compare exactly with :func:`lagrange.derive`'s, which does the same)."""
    if symbolic_parameters:
        return [(*S.m[i], S.n[i]) for i in range(mech.nlinks)]
    return [tuple(sp.Rational(x) for x in (*mech.masses[i], mech.n[i])) for i in range(mech.nlinks)]


def generic_aggregates(params):
    """Eq. (6), definitions, in any arithmetic (sympy, ring elements): ``zeta, eta, theta`` per link
    from ``params = [(m0, m1, m2, n), ...]`` (``n_i0 = 0``, ``n_i2 = 1``)."""
    zeta, eta, theta = [], [], []
    for m0, m1, m2, n in params:
        zeta.append(m1 * n**2 + m2)
        eta.append(m1 * n + m2)
        theta.append(m0 + m1 + m2)
    return zeta, eta, theta


def symbolic_aggregates(mech: Mechanism, S: Symbols, symbolic_parameters: bool):
    """``zeta, eta, theta`` per link as sympy expressions in the mass symbols, or exact numbers."""
    return generic_aggregates(_parameters(mech, S, symbolic_parameters))


def generic_coupling(mech: Mechanism, params, zero=0):
    """``(c, nu_s)`` in any arithmetic: nested lists ``c_ij = mu_ij s_i s_j`` (``zero`` for links on
    different branches) and ``nu_i s_i``; the generic twin of :func:`signed_coupling`."""
    n = mech.nlinks
    zeta, eta, theta = generic_aggregates(params)
    Theta = []
    for i in range(n):
        total = zero
        for k in range(n):
            if i in mech.ancestors[k]:
                total = total + theta[k]
        Theta.append(total)
    s = mech.sign
    c = [[zero] * n for _ in range(n)]
    nu_s = []
    for k in range(n):
        c[k][k] = zeta[k] + Theta[k]                       # First term: the link with itself
        for a in mech.ancestors[k]:                        # Second term: with each ancestor
            c[a][k] = c[k][a] = (s[a] * s[k]) * (eta[k] + Theta[k])
        nu_s.append(s[k] * (eta[k] + Theta[k]))
    return c, nu_s


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
