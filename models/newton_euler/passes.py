"""The Newton-Euler method, numpy reference: the tree's numbers (per-link mass sums, ``M_r`` factored once)
and the two passes over it, vectorised over samples.

**Inverse dynamics (forward pass, backward pass).** Per rod ``kappa_i = r_i'' = J_i q_i'' + J_i' q_i'``
(:func:`exo_bench.models.mechanism.rod_elements.rod_acceleration_3d`, times the sign). Going down the tree, a rod's start point
accelerates with ``A_k = A_parent + kappa_parent`` (a root's start is the support O, ``A = 0``).
Going up, ``D_k`` collects ``m (a + g up)`` of every point mass below link ``k``; link ``k``'s own
masses at fractions ``0, n_k, 1`` accelerate with ``A_k + f kappa_k``, so the force conjugate to
``r_k`` is

    F_k = sum_b m_kb f_b (A_k + f_b kappa_k + g up) + D_k = eta_k (A_k + g up) + zeta_k kappa_k + D_k,
    D_parent += theta_k (A_k + g up) + eta_k kappa_k + D_k,

and ``tau_k = J_k^T F_k`` (:func:`exo_bench.models.mechanism.rod_elements.project_3d`). O(n) per sample, no matrix.

**Forward dynamics.** ``tau = J^T (M_r r'' + g_r)`` with ``g_r = g nu (x) up``: ``r'' = mu^-1 (J^-T tau -
g_r)`` by the tree solve (:func:`exo_bench.models.newton_euler.passes.solve_coupling`, ``M_r`` factored at prepare time), then
``q_i'' = J_i^-1 (r_i'' - J_i' q_i')``. O(n) per sample.

Arrays are batch-first ``(samples, dof)`` in block order ``[phi..., psi..., l...]``; the loops run
over the links, each statement over every sample at once.

**The tree**: per-link mass sums, and ``M_r`` factored once.

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
names the link. The factor and the solve live in :mod:`exo_bench.models.mechanism.aggregates`, below every
method, so that the conditioning test of every method's forward dynamics uses them too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.mechanism.aggregates import link_aggregates
from exo_bench.models.mechanism.aggregates import factor_end_point_mass, solve_mu
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
    the tree's factor (:func:`exo_bench.models.mechanism.aggregates.solve_mu`). ``tree.singular`` must be -1."""
    return solve_mu(tree.parent, tree.pivot, tree.multiplier, b)


def _trig(dim, n, q):
    cf, sf = np.cos(q[:, :n]).T, np.sin(q[:, :n]).T
    if dim == 2:
        return cf, sf, None, None
    return cf, sf, np.cos(q[:, n : 2 * n]).T, np.sin(q[:, n : 2 * n]).T


def rod_accelerations(tree: Tree, dim: int, q, qd, qdd, trig=None) -> np.ndarray:
    """``kappa_i = r_i''`` of every rod, ``(n, dim, S)`` (signed)."""
    n = tree.parent.shape[0]
    cf, sf, cp, sp = _trig(dim, n, q) if trig is None else trig
    X, Xd, Xdd = q.T, qd.T, qdd.T
    s = tree.sign[:, None]
    if dim == 2:
        a = el.rod_acceleration_2d(cf, sf, X[n:], Xd[:n], Xd[n:], Xdd[:n], Xdd[n:])
    else:
        a = el.rod_acceleration_3d(
            cf, sf, cp, sp, X[2 * n :], Xd[:n], Xd[n : 2 * n], Xd[2 * n :], Xdd[:n], Xdd[n : 2 * n], Xdd[2 * n :]
        )
    return np.stack([s * c for c in a], axis=1)


def rod_forces(tree: Tree, dim: int, g: float, kappa: np.ndarray) -> np.ndarray:
    """The forward and backward passes: ``F_k`` conjugate to ``r_k``, ``(n, dim, S)``, from the rods'
    accelerations ``kappa`` ``(n, dim, S)`` (see the module docstring)."""
    n = kappa.shape[0]
    parent, zeta, eta, theta = tree.parent, tree.zeta, tree.eta, tree.theta
    A = np.zeros_like(kappa)  # start-point accelerations, roots first
    for k in range(n):
        p = parent[k]
        if p >= 0:
            A[k] = A[p] + kappa[p]
    A[:, dim - 1] += g  # A + g up: the weight enters like an acceleration
    D = np.zeros_like(kappa)
    F = np.empty_like(kappa)
    for k in range(n - 1, -1, -1):  # leaves first
        F[k] = el.rod_force(zeta[k], eta[k], A[k], kappa[k], D[k])
        p = parent[k]
        if p >= 0:
            D[p] += el.subtree_share(theta[k], eta[k], A[k], kappa[k], D[k])
    return F


def _per_rod(tree, dim, trig, l, V, planar, spatial) -> np.ndarray:
    """``s_k * element(trig_k, l_k, V_k)`` of every rod as ``(S, dof)`` in block order, with the
    element function ``planar`` or ``spatial`` of :mod:`exo_bench.models.mechanism.rod_elements` (``V``: ``(n, dim, S)``)."""
    cf, sf, cp, sp = trig
    s = tree.sign[:, None]
    if dim == 2:
        parts = planar(cf, sf, l, V[:, 0], V[:, 1])
    else:
        parts = spatial(cf, sf, cp, sp, l, V[:, 0], V[:, 1], V[:, 2])
    return np.concatenate([s * x for x in parts], axis=0).T


def _project(tree, dim, trig, l, F) -> np.ndarray:
    """``tau_k = J_k^T F_k`` of every rod, ``(S, dof)``."""
    return _per_rod(tree, dim, trig, l, F, el.project_2d, el.project_3d)


def inverse_dynamics(tree: Tree, dim: int, g: float, q, qd, qdd) -> np.ndarray:
    """Generalised forces ``tau (S, dof)`` by the two passes, O(n) per sample."""
    n = tree.parent.shape[0]
    trig = _trig(dim, n, q)
    kappa = rod_accelerations(tree, dim, q, qd, qdd, trig)
    return _project(tree, dim, trig, q[:, -n:].T, rod_forces(tree, dim, g, kappa))


def rod_loads(tree: Tree, dim: int, q, tau) -> np.ndarray:
    """``J^-T tau``: the force on each rod conjugate to ``r_i``, ``(n, dim, S)``; divides by ``l_i``
    (and ``cos psi_i`` in 3D)."""
    n = tree.parent.shape[0]
    cf, sf, cp, sp = _trig(dim, n, q)
    l, T = q[:, -n:].T, tau.T
    s = tree.sign[:, None]
    if dim == 2:
        f = el.unproject_2d(cf, sf, l, T[:n], T[n:])
    else:
        f = el.unproject_3d(cf, sf, cp, sp, l, T[:n], T[n : 2 * n], T[2 * n :])
    return np.stack([s * x for x in f], axis=1)


def rod_vector_accelerations(tree: Tree, dim: int, g: float, f) -> np.ndarray:
    """``r'' = M_r^-1 (f - g_r)``, ``(n, dim, S)``, for loads ``f`` conjugate to ``r`` ``(n, dim, S)``."""
    b = f.copy()
    b[:, dim - 1] -= g * tree.nu[:, None]
    return solve_coupling(tree, b)


def coordinate_rates(tree: Tree, dim: int, q, v) -> np.ndarray:
    """``J^-1 v``, ``(S, dof)``: coordinate rates (or accelerations) of rod-vector rates ``v`` ``(n, dim, S)``."""
    n = tree.parent.shape[0]
    return _per_rod(tree, dim, _trig(dim, n, q), q[:, -n:].T, v, el.rates_2d, el.rates_3d)


def forward_dynamics(tree: Tree, dim: int, g: float, q, qd, tau) -> np.ndarray:
    """``qdd (S, dof)`` with ``M(q) qdd + h(q, qd) = tau``, O(n) per sample (module docstring)."""
    bias = rod_accelerations(tree, dim, q, qd, np.zeros_like(q))  # J' q'
    rdd = rod_vector_accelerations(tree, dim, g, rod_loads(tree, dim, q, tau))
    return coordinate_rates(tree, dim, q, rdd - bias)


def jacobian_columns(tree: Tree, dim: int, q) -> np.ndarray:
    """``J`` as ``(S, dof, dim)``: row ``a`` is ``d r_i / d q_a`` of the rod ``i`` of coordinate ``a``."""
    n = tree.parent.shape[0]
    S = q.shape[0]
    out = np.empty((S, dim * n, dim))
    eye = np.eye(dim)
    for c in range(dim):  # J^T e_c, column by column of the identity
        F = np.broadcast_to(eye[c][None, :, None], (n, dim, S))
        out[:, :, c] = _project(tree, dim, _trig(dim, n, q), q[:, -n:].T, F)
    return out


def mass_matrix(tree: Tree, dim: int, mu: np.ndarray, q) -> np.ndarray:
    """``M(q) = J^T (mu (x) I) J``, ``(S, dof, dof)``: ``M[a, b] = mu_ij J_a . J_b`` (O(n^2) for the
    output only)."""
    n = tree.parent.shape[0]
    J = jacobian_columns(tree, dim, q)
    link = np.tile(np.arange(n), dim)
    return mu[link][:, link][None] * (J @ np.swapaxes(J, 1, 2))
