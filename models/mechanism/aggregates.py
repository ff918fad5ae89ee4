"""The mass aggregates of eq. (6) and the mass coupling ``mu`` of the kinetic energy: one definition.

Link ``i`` carries point masses ``m_i0, m_i1, m_i2`` at fractions ``0, n_i, 1`` of its rod vector
``w_i = s_i l_i u_i``. Eq. (6) defines, per link,

    zeta_i = sum_b m_ib n_ib^2 = m_i1 n_i^2 + m_i2,
    eta_i  = sum_b m_ib n_ib   = m_i1 n_i + m_i2,
    theta_i = sum_b m_ib       = m_i0 + m_i1 + m_i2,

and, on a tree, ``Theta(k)`` the total mass of the strict descendants of link ``k`` (for a chain
``sum_{j > k} theta_j``, the sum in the bracket of eq. (6)). Point mass ``b`` of link ``i`` sits at
``r_ib = sum_{a in anc(i)} w_a + n_ib w_i``, hence

    T = 1/2 sum_ij mu_ij  d/dt(w_i) . d/dt(w_j),      Pi = g sum_k nu_k (w_k . up)

with the mass coupling

* ``mu_ii = zeta_i + Theta(i)``                      (every descendant mass moves with w_i);
* ``mu_ij = eta_k + Theta(k)`` if ``i`` and ``j`` are related (one is an ancestor of the other)
  and ``k`` is the deeper of the two (link k's own masses at fractions n_kb, and every
  descendant of k at fraction 1, ride on both rods);
* ``mu_ij = 0`` for links on different branches (no mass rides on both);
* ``nu_k = eta_k + Theta(k)``.

For a chain ``mu`` is exactly the bracket of eq. (6). The matrix method multiplies ``mu`` by the
branch signs (:mod:`exo_bench.matrix_method.closed_forms.coefficients`), forward dynamics uses it to find where ``M`` is
singular (:mod:`exo_bench.models.simulation.forward_dynamics`). The functions :func:`aggregates` and
:func:`coupling_entries` are written for any arithmetic (floats, numpy arrays, sympy expressions,
polynomial-ring elements), so the numeric and the symbolic coefficients are the same definition.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism


def aggregates(m0, m1, m2, n):
    """Eq. (6), definitions: ``(zeta, eta, theta)`` of a link with masses ``m0, m1, m2`` at fractions
    ``0, n, 1``, in any arithmetic (scalars, numpy arrays of links, sympy, ring elements)."""
    return m1 * n**2 + m2, m1 * n + m2, m0 + m1 + m2


def link_aggregates(mech: Mechanism) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (6), definitions, for every link of ``mech``: ``zeta, eta, theta``, each ``(n,)``."""
    m = mech.mass_array
    return aggregates(m[:, 0], m[:, 1], m[:, 2], np.asarray(mech.n, dtype=float))


def descendant_sums(mech: Mechanism, theta, zero=0) -> list:
    """Eq. (6), the sum ``sum_{k=j+1..n} theta_k`` on a tree: ``Theta(k)``, the sum of ``theta``
    over the strict descendants of each link (any arithmetic; ``zero`` its zero)."""
    out = [zero] * mech.nlinks
    for k in range(mech.nlinks):
        for a in mech.ancestors[k]:
            out[a] = out[a] + theta[k]
    return out


def coupling_entries(mech: Mechanism, zeta, eta, theta, zero=0) -> tuple[list[list], list]:
    """Eq. (6) generalised to trees, in any arithmetic: ``mu`` as nested lists and ``nu`` as a list
    (see the module docstring), from the per-link aggregates."""
    n = mech.nlinks
    Theta = descendant_sums(mech, theta, zero)
    mu = [[zero] * n for _ in range(n)]
    nu = []
    for k in range(n):
        mu[k][k] = zeta[k] + Theta[k]  # First term: the link with itself
        for a in mech.ancestors[k]:  # Second term: k with each ancestor, k deeper
            mu[a][k] = mu[k][a] = eta[k] + Theta[k]
        nu.append(eta[k] + Theta[k])
    return mu, nu


@lru_cache(maxsize=256)
def _numeric(mech: Mechanism) -> tuple[np.ndarray, np.ndarray]:
    mu_entries, nu_entries = coupling_entries(mech, *link_aggregates(mech), zero=0.0)
    mu = np.array(mu_entries, dtype=float).reshape(mech.nlinks, mech.nlinks)
    nu = np.array(nu_entries, dtype=float)
    mu.flags.writeable = False
    nu.flags.writeable = False
    return mu, nu


def descendant_mass(mech: Mechanism) -> np.ndarray:
    """``Theta(k)``, the total mass of the strict descendants of each link, ``(n,)``."""
    return np.array(descendant_sums(mech, link_aggregates(mech)[2], 0.0), dtype=float)


def coupling(mech: Mechanism) -> np.ndarray:
    """Eq. (6) generalised to trees: the symmetric ``(n, n)`` mass coupling ``mu_ij`` of
    ``T = 1/2 sum_ij mu_ij w_i' . w_j'`` (the mass distribution matrix). Read-only, cached per
    mechanism."""
    return _numeric(mech)[0]


def gravity_coupling(mech: Mechanism) -> np.ndarray:
    """``nu_k = eta_k + Theta(k)``, ``(n,)``, of ``Pi = g sum_k nu_k (w_k . up)``. Read-only, cached."""
    return _numeric(mech)[1]
