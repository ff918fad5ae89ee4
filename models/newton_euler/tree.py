"""The tree of the Newton-Euler method: per-link mass sums, and ``M_r`` factored once.

**The constant mass matrix.** A point mass ``m`` of link ``k`` at fraction ``f`` in ``{0, n_k, 1}``
sits at ``P = sum_{a in anc(k)} r_a + f r_k``, so ``T = 1/2 sum_ij mu_ij r_i' . r_j'`` with the
constant mass coupling ``mu`` of :func:`exo_bench.models.mechanism.aggregates.coupling`: ``M_r = mu (x) I_d``
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
names the link. The factor and the solve live in :mod:`exo_bench.models.mechanism.mass_factor`, below every
method, so that the conditioning test of every method's forward dynamics uses them too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.models.mechanism.aggregates import link_aggregates
from exo_bench.models.mechanism.mass_factor import factor_end_point_mass, solve_mu
from exo_bench.models.mechanism.mechanism import Mechanism


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


def prepare_tree(mech: Mechanism) -> Tree:
    """All per-mechanism numbers of the Newton-Euler method, O(n) time and memory (no ``n x n``
    array: ``nu_k = eta_k + Theta(k)`` of :mod:`exo_bench.models.mechanism.aggregates` with the descendant masses
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
    """``mu^-1 b`` for ``b`` of shape ``(n, ...)`` (any trailing axes: components, samples), O(n), by
    the tree's factor (:func:`exo_bench.models.mechanism.mass_factor.solve_mu`). ``tree.singular`` must be -1."""
    return solve_mu(tree.parent, tree.pivot, tree.multiplier, b)
