"""The tree of the Newton-Euler method: per-link mass sums, and ``M_r`` factored once.

**The constant mass matrix.** A point mass ``m`` of link ``k`` at fraction ``f`` in ``{0, n_k, 1}``
sits at ``P = sum_{a in anc(k)} r_a + f r_k``, so ``T = 1/2 sum_ij mu_ij r_i' . r_j'`` with the
constant mass coupling ``mu`` of :func:`exo_bench.models.aggregates.coupling`: ``M_r = mu (x) I_d``
(independent of the configuration; the signs are inside ``r_i = s_i l_i u_i``).

**O(n) solves with M_r.** Put ``e = T r``, the rods' end points: ``T`` sums the rod vectors down
the tree, ``T^-1`` takes one difference with the parent (``r_k = e_k - e_parent(k)``, the support
O fixed). In end points the masses of link ``k`` sit at ``e_p`` (start, ``p`` its parent),
``(1 - n_k) e_p + n_k e_k`` (middle) and ``e_k`` (end), so::

    T = 1/2 sum_k [ m_k0 |e_p'|^2 + m_k1 |(1 - n_k) e_p' + n_k e_k'|^2 + m_k2 |e_k'|^2 ]

and ``mu = T^T M_e T`` with ``M_e`` coupling each end point only with its parent's, through the
middle mass (``M_e[k, p] = m_k1 n_k (1 - n_k)``). Eliminating the links leaves first (children
have larger indices than their parents), ``M_e = L D L^T`` has no fill-in: one pivot ``d_k`` and
one multiplier ``l_k`` per link. Then ``mu^-1 b = T^-1 M_e^-1 T^-T b`` costs three passes over
the tree (:func:`solve_coupling`). :func:`factor_end_point_mass` factors it once, at prepare
time; a pivot that vanishes means that ``M_r`` is singular, and :func:`singular_mass_reason`
names the link.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.models.aggregates import link_aggregates
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.singularity import massless_reason

#: A pivot ``d_k`` of ``M_e`` at or below this share of its diagonal entry counts as zero: the
#: elimination subtracted everything (an end point that carries no mass of its own). A few
#: roundings of the subtraction stay far below it.
PIVOT_RTOL = 64 * float(np.finfo(float).eps)


@dataclass(frozen=True)
class Tree:
    """Per-mechanism numbers of the two passes and of the solve with ``M_r``, all ``(n,)``.

    ``parent`` (``-1`` at a root), ``sign``, the aggregates of eq. (6) ``zeta`` (mass times fraction
    squared), ``eta`` (mass times fraction), ``theta`` (mass), ``nu`` (gravity coefficients), and the
    factor of ``M_e``: ``pivot`` ``d_k`` and ``multiplier`` ``l_k`` (0 at a root). ``singular``: the
    0-based link whose pivot vanished, or -1."""

    parent: np.ndarray
    sign: np.ndarray
    zeta: np.ndarray
    eta: np.ndarray
    theta: np.ndarray
    nu: np.ndarray
    pivot: np.ndarray
    multiplier: np.ndarray
    singular: int

    def table(self) -> np.ndarray:
        """The numbers as one C-ordered ``(8, n)`` float array for the compiled kernels: rows
        ``parent, sign, zeta, eta, theta, nu, pivot, multiplier``."""
        t = np.ascontiguousarray(
            np.stack(
                [
                    self.parent.astype(float),
                    self.sign,
                    self.zeta,
                    self.eta,
                    self.theta,
                    self.nu,
                    self.pivot,
                    self.multiplier,
                ]
            )
        )
        t.flags.writeable = False
        return t


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


def singular_mass_reason(mech: Mechanism, k: int) -> str:
    """Why ``M_r`` is singular at link ``k`` (0-based), in the words of :mod:`exo_bench.models.singularity`."""
    return (
        massless_reason(mech, k)
        if (mech.masses[k][1] == 0 and mech.masses[k][2] == 0 and k not in mech.parent)
        else f"link {k + 1} ({mech.names[k]}): zero mass: no mass moves with its end point while the other "
        "end points are held (M_r is singular)"
    )


def prepare_tree(mech: Mechanism) -> Tree:
    """All per-mechanism numbers of the Newton-Euler method, O(n) time and memory (no ``n x n``
    array: ``nu_k = eta_k + Theta(k)`` of :mod:`exo_bench.models.aggregates` with the descendant masses
    ``Theta`` summed leaves first)."""
    zeta, eta, theta = link_aggregates(mech)
    below = np.zeros(mech.nlinks)  # Theta(k): the mass of k's strict descendants
    for k in range(mech.nlinks - 1, -1, -1):
        p = mech.parent[k]
        if p >= 0:
            below[p] += theta[k] + below[k]
    pivot, mult, singular = factor_end_point_mass(mech)
    return Tree(
        np.asarray(mech.parent, dtype=np.int64),
        mech.sign_array.copy(),
        zeta,
        eta,
        theta,
        eta + below,
        pivot,
        mult,
        singular,
    )


def solve_coupling(tree: Tree, b: np.ndarray) -> np.ndarray:
    """``mu^-1 b`` for ``b`` of shape ``(n, ...)`` (any trailing axes: components, samples), O(n).

    ``z = T^-T b`` (``z_a = b_a - sum_{children c} b_c``), ``M_e y = z`` by the factor (leaves first,
    then roots first), ``x = T^-1 y`` (``x_k = y_k - y_parent``). ``tree.singular`` must be -1."""
    n = b.shape[0]
    parent, d, lk = tree.parent, tree.pivot, tree.multiplier
    z = b.copy()
    for k in range(n - 1, -1, -1):  # T^-T: subtract each child's entry from its parent's
        p = parent[k]
        if p >= 0:
            z[p] -= b[k]
    for k in range(n - 1, -1, -1):  # L^-1, leaves first
        p = parent[k]
        if p >= 0:
            z[p] -= lk[k] * z[k]
    y = np.empty_like(z)
    for k in range(n):  # D^-1 L^-T, roots first
        p = parent[k]
        y[k] = z[k] / d[k] - (lk[k] * y[p] if p >= 0 else 0.0)
    x = y.copy()
    for k in range(n):  # T^-1: one difference with the parent
        p = parent[k]
        if p >= 0:
            x[k] = y[k] - y[p]
    return x
