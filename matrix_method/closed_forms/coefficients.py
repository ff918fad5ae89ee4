"""The mass coefficients of the closed forms: the aggregates of eq. (6) with the branch signs.

The aggregates ``zeta, eta, theta`` of eq. (6), the descendant masses ``Theta`` and the mass
coupling ``mu_ij`` / gravity coefficients ``nu_k`` of ``T = 1/2 sum_ij mu_ij w_i' . w_j'`` and
``Pi = g sum_k nu_k (w_k . up)`` are defined once, in :mod:`exo_bench.models.mechanism.aggregates` (derivation there).
Every matrix element of eqs. (5) and (17) is ``c_ij = mu_ij s_i s_j`` times a geometric factor of
links i and j (:mod:`exo_bench.matrix_method.closed_forms.planar`), so the sign products of a branched model ("reversed
links contribute sign products") live in ``c`` alone; this module adds them.

Each formula is written once, in any arithmetic (:func:`generic_aggregates`, :func:`signed_coupling_entries`,
:func:`increments`); the numeric forms (floats from the mechanism, cached arrays) and the symbolic ones
(ring elements, CasADi, and the sympy expressions of
:mod:`exo_bench.matrix_method.symbolic`) call it. This module imports no
sympy: the compiled and numpy kernels read their coefficients here (tests/test_numeric_imports.py).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from exo_bench.models.mechanism.aggregates import aggregates, coupling_entries, link_aggregates
from exo_bench.models.mechanism.mechanism import Mechanism


# ----------------------------------------------------------------- numeric
@lru_cache(maxsize=256)
def _signed(mech: Mechanism) -> tuple[np.ndarray, np.ndarray]:
    """:func:`signed_coupling_entries` on the mechanism's floats, as read-only arrays."""
    c, nu_s = signed_coupling_entries(mech, *link_aggregates(mech), zero=0.0)
    out = np.array(c, dtype=float).reshape(mech.nlinks, mech.nlinks), np.array(nu_s, dtype=float)
    for a in out:
        a.flags.writeable = False
    return out


def signed_coupling(mech: Mechanism) -> np.ndarray:
    """``c_ij = mu_ij s_i s_j``, the coefficient every closed-form element carries, ``(n, n)``."""
    return _signed(mech)[0]


def signed_gravity(mech: Mechanism) -> np.ndarray:
    """``nu_i s_i`` with ``nu_i = eta_i + Theta(i)``: the coefficient of the gravity vectors ``P``."""
    return _signed(mech)[1]


def increments(mech: Mechanism, k: int, zeta_k, eta_k, theta_k, dtype=float):
    """Eq. (25) generalised to trees, in any arithmetic: what adding link ``k`` (aggregates ``zeta_k,
    eta_k, theta_k``) does to the coefficients.

    Returns ``(idx, dc, dnu_s)``: the links concerned (the ancestors of k, then k itself), the
    increment of ``c`` on ``idx x idx`` and the increment of ``nu s`` on ``idx``, as arrays of
    ``dtype`` (``object`` for sympy or ring elements). ``theta_k s_i s_j`` on ancestor pairs (k adds
    to Theta of each ancestor), ``eta_k s_i s_k`` on the new row and column, ``zeta_k`` in the
    corner; ``theta_k s_i`` and ``eta_k s_k`` for gravity.
    """
    idx = np.array(sorted(mech.ancestors[k]) + [k], dtype=int)
    s = np.array([mech.sign[i] for i in idx], dtype=dtype)
    dc = np.outer(s, s) * theta_k  # First term: old block, ancestors only
    dc[-1, :] = dc[:, -1] = s * s[-1] * eta_k  # Second term: the new row and column
    dc[-1, -1] = zeta_k  # Third term: the corner
    dnu = s * theta_k
    dnu[-1] = s[-1] * eta_k
    return idx, dc, dnu


def recurrence_increments(mech: Mechanism, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`increments` of link ``k`` on the mechanism's floats."""
    zeta, eta, theta = link_aggregates(mech)
    return increments(mech, k, zeta[k], eta[k], theta[k])


# ------------------------------------------------------------- any arithmetic
def generic_aggregates(params):
    """Eq. (6), definitions, in any arithmetic (sympy, ring elements): ``zeta, eta, theta`` per link
    from ``params = [(m0, m1, m2, n), ...]`` (:func:`exo_bench.models.mechanism.aggregates.aggregates`)."""
    per_link = [aggregates(*p) for p in params]
    return [a[0] for a in per_link], [a[1] for a in per_link], [a[2] for a in per_link]


def generic_coupling(mech: Mechanism, params, zero=0):
    """``(c, nu_s)`` in any arithmetic: nested lists ``c_ij = mu_ij s_i s_j`` (``zero`` for links on
    different branches) and ``nu_i s_i``; the generic twin of :func:`signed_coupling`, built on
    :func:`exo_bench.models.mechanism.aggregates.coupling_entries`."""
    zeta, eta, theta = generic_aggregates(params)
    return signed_coupling_entries(mech, zeta, eta, theta, zero=zero)


def signed_coupling_entries(mech: Mechanism, zeta, eta, theta, zero=0):
    """``(c, nu_s)`` from the per-link aggregates of eq. (6), in any arithmetic (symbols for the
    aggregates themselves: the LaTeX export): the branch signs added to
    :func:`exo_bench.models.mechanism.aggregates.coupling_entries`."""
    n = mech.nlinks
    mu, nu = coupling_entries(mech, zeta, eta, theta, zero=zero)
    s = mech.sign
    related = mech.ancestor_or_self
    c = [
        [(s[i] * s[j]) * mu[i][j] if i != j and (related[i, j] or related[j, i]) else mu[i][j] for j in range(n)]
        for i in range(n)
    ]  # the diagonal has s_i^2 = 1, unrelated links zero
    return c, [s[k] * nu[k] for k in range(n)]


def generic_recurrence_increments(mech: Mechanism, params, k: int):
    """:func:`increments` of link ``k`` in any arithmetic (``params`` as for :func:`generic_aggregates`),
    as object arrays."""
    zeta, eta, theta = aggregates(*params[k])
    return increments(mech, k, zeta, eta, theta, dtype=object)
