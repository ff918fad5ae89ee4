"""Closed forms of every matrix of eq. (5), the planar model, for trees with branch signs.

Derivation (verified by the tests against Lagrange's equations and Pinocchio). With
``T = 1/2 sum_ij c_ij d/dt(l_i u_i) . d/dt(l_j u_j)``, ``c_ij = mu_ij s_i s_j``
(:mod:`exo_bench.matrix_method.closed_forms.coefficients`) and ``Pi = g sum_i nu_i s_i l_i (u_i . up)``, the rod vector
``l_i u_i`` depends on link i's own coordinates only, so Lagrange's equation of coordinate ``a`` of
link ``i`` is

    tau_a = r_a . sum_j c_ij d2/dt2(l_j u_j) + g nu_i s_i r_a . up,
    r_phi = l_i du_i/dphi_i,   r_l = u_i,

and ``d2/dt2(l u) = l u_phi phi'' + u l'' + l u_phiphi phi'^2 + 2 u_phi phi' l'``: only products of
link j's own rates appear, which is the form of eq. (5). In 2D ``u = (cos phi, sin phi)``,
``u_phi = (-sin phi, cos phi)``, ``u_phiphi = -u``, and with ``C_ij = cos(phi_i - phi_j)``,
``S_ij = sin(phi_i - phi_j)``:

    u_phi_i . u_phi_j = C_ij,  u_phi_i . u_j = -S_ij,  u_i . u_phi_j = S_ij,  u_i . u_j = C_ij.

Hence the ten closed forms below (row i, column j). They generalise the paper's chain formulas:
the sum ``sum_{k=j+1..n} theta_k`` of eq. (6) becomes the mass of the deeper link's descendants,
elements of links on different branches vanish (``c_ij = 0``), and reversed links contribute the
sign product ``s_i s_j`` (both inside ``c_ij``). For Fig. 2a/2b they are the entries of eq. (4).

Every function is written once for both backends: numpy arrays that broadcast (``c`` of shape
``(n, n)``, ``li`` ``(S, n, 1)``, ``lj`` ``(S, 1, n)``, ``C, S`` ``(S, n, n)``) or sympy scalars of
one entry. The recurrence (:mod:`exo_bench.matrix_method.recurrence`) calls them with increments of ``c``.
"""

from __future__ import annotations


def a_phi(c, li, lj, C, S):
    """Eq. (6) generalised to trees: ``2D a^phi_ij = c_ij l_i l_j cos(phi_i - phi_j)``.

    ``c_ij = (delta_ij zeta_i + (1 - delta_ij) eta_k + Theta(k)) s_i s_j`` with k the deeper of i, j
    and ``Theta(k)`` the mass of its descendants; for a chain this is eq. (6) exactly.
    From ``r_phi_i . l_j u_phi_j = l_i l_j C_ij``. Symmetric.
    """
    return c * li * lj * C


def lam_phi(c, li, lj, C, S):
    """Eq. (5), matrix Lambda_phi: ``2D lambda^phi_ij = -c_ij l_i sin(phi_i - phi_j)``.

    From ``r_phi_i . u_j = l_i u_phi_i . u_j = -l_i S_ij``; eq. (4): ``-+ l1 eta2 S12 l2''``.
    """
    return -(c * li * S)


def d_phi(c, li, lj, C, S):
    """Eq. (5), matrix D_phi: ``2D d^phi_ij = c_ij l_i l_j sin(phi_i - phi_j)`` (zero diagonal).

    From ``r_phi_i . l_j u_phiphi_j = -l_i l_j u_phi_i . u_j = l_i l_j S_ij``; eq. (4):
    ``+- l1 l2 eta2 S12 phi2'^2``.
    """
    return c * li * lj * S


def h_phi(c, li, lj, C, S):
    """Eq. (5), matrix H_phi: ``2D h^phi_ij = c_ij l_i cos(phi_i - phi_j)`` (the ``2H`` term).

    From ``r_phi_i . u_phi_j = l_i C_ij``; eq. (4): ``2 (zeta1 + theta2) l1 l1' phi1'``.
    """
    return c * li * C


def p_phi(nu_s, li, cos_i, sin_i):
    """Eq. (5), vector P_phi: ``2D p^phi_i = nu_i s_i l_i cos(phi_i)`` (times g in the equation).

    From ``r_phi_i . up = l_i cos phi_i``, ``nu_i = eta_i + Theta(i)``; eq. (4):
    ``(eta1 + theta2) g l1 C1``. ``cos_i, sin_i`` are those of the angle ``phi_i``.
    """
    return nu_s * li * cos_i


def a_l(c, li, lj, C, S):
    """Eq. (5), matrix A_l: ``2D a^l_ij = c_ij l_j sin(phi_i - phi_j)`` (``= (Lambda_phi)^T``).

    From ``r_l_i . l_j u_phi_j = l_j u_i . u_phi_j = l_j S_ij``; eq. (4): ``+- l2 eta2 S12 phi2''``.
    """
    return c * lj * S


def lam_l(c, li, lj, C, S):
    """Eq. (5), matrix Lambda_l: ``2D lambda^l_ij = c_ij cos(phi_i - phi_j)``. Symmetric.

    From ``u_i . u_j = C_ij``; eq. (4): ``(zeta1 + theta2) l1''``, ``+- eta2 C12 l2''``.
    """
    return c * C


def d_l(c, li, lj, C, S):
    """Eq. (5), matrix D_l: ``2D d^l_ij = -c_ij l_j cos(phi_i - phi_j)`` (``= -(H_phi)^T``).

    From ``u_i . l_j u_phiphi_j = -l_j C_ij``; eq. (4): ``-(zeta1 + theta2) l1 phi1'^2``.
    """
    return -(c * lj * C)


def h_l(c, li, lj, C, S):
    """Eq. (5), matrix H_l: ``2D h^l_ij = c_ij sin(phi_i - phi_j)`` (zero diagonal).

    From ``u_i . u_phi_j = S_ij``; eq. (4): ``+- 2 eta2 S12 l2' phi2'``.
    """
    return c * S


def p_l(nu_s, li, cos_i, sin_i):
    """Eq. (5), vector P_l: ``2D p^l_i = nu_i s_i sin(phi_i)`` (times g in the equation).

    From ``r_l_i . up = sin phi_i``; eq. (4): ``(eta1 + theta2) g S1``.
    """
    return nu_s * sin_i


#: The pair elements of eq. (5) by block and matrix name (the convention of :mod:`lagrange`).
PAIRS = {
    "phi": {"A": a_phi, "Lambda": lam_phi, "D": d_phi, "H": h_phi},
    "l": {"A": a_l, "Lambda": lam_l, "D": d_l, "H": h_l},
}
#: The gravity vectors of eq. (5) by block.
GRAVITY = {"phi": p_phi, "l": p_l}
