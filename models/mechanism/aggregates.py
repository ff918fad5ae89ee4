"""The mass aggregates of eq. (6) and the mass coupling ``mu`` of the kinetic energy: one definition, and
``mu`` factored in O(n).

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

**The factor.** ``mu = T^T M_e T``, with products and solves in O(n).

**End points.** Put ``e = T r``, the rods' end points: ``T`` sums the rod vectors down the tree,
``T^-1`` takes one difference with the parent (``r_k = e_k - e_parent(k)``, the support O fixed). In
end points the masses of link ``k`` sit at ``e_p`` (start, ``p`` its parent), ``(1 - n_k) e_p + n_k
e_k`` (middle) and ``e_k`` (end), so::

    T = 1/2 sum_k [ m_k0 |e_p'|^2 + m_k1 |(1 - n_k) e_p' + n_k e_k'|^2 + m_k2 |e_k'|^2 ]

and ``mu = T^T M_e T`` with ``M_e`` coupling each end point only with its parent's, through the
middle mass (``M_e[k, p] = m_k1 n_k (1 - n_k)``). Eliminating the links leaves first (children have
larger indices than their parents), ``M_e = L D L^T`` has no fill-in: one pivot ``d_k`` and one
multiplier ``l_k`` per link. Then ``mu^-1 b = T^-1 M_e^-1 T^-T b`` costs three passes over the tree
(:func:`solve_mu`) and ``mu x`` three more (:func:`multiply_mu`). :func:`factor_end_point_mass`
factors it once; a pivot that vanishes means that ``mu`` is singular.

Used by the Newton-Euler method's forward dynamics (:mod:`exo_bench.models.newton_euler.passes`) and by the
conditioning test that every method's forward dynamics shares (:mod:`exo_bench.models.runtime.conditioning`),
which is why it sits here, below both.
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


#: A pivot ``d_k`` of ``M_e`` at or below this share of its diagonal entry counts as zero: the
#: elimination subtracted everything (an end point that carries no mass of its own). A few
#: roundings of the subtraction stay far below it.
PIVOT_RTOL = 64 * float(np.finfo(float).eps)


def end_point_mass(mech: Mechanism) -> tuple[np.ndarray, np.ndarray]:
    """``M_e`` as its diagonal ``(n,)`` and its parent entries ``off[k] = M_e[k, parent(k)]`` (0 at a
    root, where the parent's end point is the fixed support)."""
    m = mech.mass_array
    f = np.asarray(mech.n, dtype=float)
    diag = m[:, 2] + m[:, 1] * f**2
    off = np.zeros(mech.nlinks)
    for k, p in enumerate(mech.parent):
        if p >= 0:
            diag[p] += m[k, 0] + m[k, 1] * (1.0 - f[k]) ** 2
            off[k] = m[k, 1] * f[k] * (1.0 - f[k])
    return diag, off


def factor_end_point_mass(mech: Mechanism) -> tuple[np.ndarray, np.ndarray, int]:
    """``M_e = L D L^T`` eliminated leaves first: ``(pivot, multiplier, singular)``, O(n).

    Eliminating link ``k`` (after all its children) takes its pivot ``d_k``, the multiplier
    ``l_k = M_e[k, p] / d_k`` and subtracts ``l_k M_e[k, p]`` from the parent's diagonal. A pivot at or
    below :data:`PIVOT_RTOL` times its diagonal entry marks ``M_e`` (hence ``M_r``) singular; the
    first such link (deepest first) is returned, else -1."""
    diag, off = end_point_mass(mech)
    d = diag.copy()
    mult = np.zeros(mech.nlinks)
    singular = -1
    for k in range(mech.nlinks - 1, -1, -1):
        if d[k] <= PIVOT_RTOL * diag[k] or d[k] <= 0.0:
            singular = k if singular < 0 else singular
            d[k] = 0.0
            continue
        p = mech.parent[k]
        if p >= 0:
            mult[k] = off[k] / d[k]
            d[p] -= mult[k] * off[k]
    return d, mult, singular


def solve_mu(parent: np.ndarray, pivot: np.ndarray, multiplier: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``mu^-1 b`` for ``b`` of shape ``(n, ...)`` (any trailing axes: components, samples), O(n).

    ``z = T^-T b`` (``z_a = b_a - sum_{children c} b_c``), ``M_e y = z`` by the factor (leaves first,
    then roots first), ``x = T^-1 y`` (``x_k = y_k - y_parent``). No pivot may be zero."""
    n = b.shape[0]
    dtype = np.result_type(b.dtype, float)  # complex stays complex (complex-step tests of forward dynamics)
    parent = np.asarray(parent).tolist()  # Python ints: the loops index with them
    d, lk = pivot, multiplier
    if b.ndim == 1:  # one vector (the condition estimate): Python floats, 5x faster than numpy scalars
        d, lk, b = d.tolist(), lk.tolist(), b.tolist()
    z = list(b) if isinstance(b, list) else b.copy()
    for k in range(n - 1, -1, -1):  # T^-T: subtract each child's entry from its parent's
        p = parent[k]
        if p >= 0:
            z[p] -= b[k]
    for k in range(n - 1, -1, -1):  # L^-1, leaves first
        p = parent[k]
        if p >= 0:
            z[p] -= lk[k] * z[k]
    y = list(z) if isinstance(z, list) else np.empty_like(z)
    for k in range(n):  # D^-1 L^-T, roots first
        p = parent[k]
        y[k] = z[k] / d[k] - (lk[k] * y[p] if p >= 0 else 0.0)
    x = list(y) if isinstance(y, list) else y.copy()
    for k in range(n):  # T^-1: one difference with the parent
        p = parent[k]
        if p >= 0:
            x[k] = y[k] - y[p]
    return np.asarray(x, dtype=dtype)


def multiply_mu(parent: np.ndarray, diag: np.ndarray, off: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``mu x`` for ``x`` of shape ``(n,)``, O(n): ``T^T (M_e (T x))`` with ``M_e`` as
    :func:`end_point_mass` gives it."""
    n = x.shape[0]
    parent = np.asarray(parent).tolist()
    diag, off = diag.tolist(), off.tolist()
    e = x.astype(float).tolist()
    for k in range(n):  # T: end points, roots first
        p = parent[k]
        if p >= 0:
            e[k] += e[p]
    y = [a * b for a, b in zip(diag, e)]
    for k in range(n):
        p = parent[k]
        if p >= 0:
            y[k] += off[k] * e[p]
            y[p] += off[k] * e[k]
    for k in range(n - 1, -1, -1):  # T^T: subtree sums, leaves first
        p = parent[k]
        if p >= 0:
            y[p] += y[k]
    return np.asarray(y, dtype=float)
