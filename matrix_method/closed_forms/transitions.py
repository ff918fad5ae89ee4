"""The transition formulas (18): each 3D matrix element from the planar elements of a model of the
same structure, verified, misprints corrected, removable singularities removed.

Derivation. In 3D ``u = (cos psi cos phi, cos psi sin phi, sin psi)`` and the same Lagrange argument
as in :mod:`exo_bench.matrix_method.closed_forms.planar` gives, for coordinate ``a`` of link i,
``tau_a = r_a . sum_j c_ij d2/dt2(l_j u_j) + g nu_i s_i r_a . up`` with ``r_phi = l_i u_phi``,
``r_psi = l_i u_psi``, ``r_l = u_i``, and

    d2/dt2(l u) = l u_phi phi'' + l u_psi psi'' + u l'' + l u_phiphi phi'^2 + l u_psipsi psi'^2
                  + 2 l u_phipsi phi' psi' + 2 u_phi phi' l' + 2 u_psi psi' l',

which is the form of eq. (17), term by term (A, B, Lambda, D, E, G, H, K). With
``c_i = cos psi_i``, ``s_i = sin psi_i`` and ``C = cos(phi_i - phi_j)``, ``S = sin(phi_i - phi_j)``
the dot products are, e.g., ``u_phi_i . u_phi_j = c_i c_j C``, ``u_psi_i . u_psi_j = s_i s_j C + c_i c_j``,
``u_i . u_psi_j = s_i c_j - c_i s_j C``, ``u_psi_i . u_phipsi_j = s_i s_j S``. Comparing each with the
planar element that has the same ``phi``-structure gives the formulas below; every one is the
printed (18) line after correction (the errata study, ``exo-bench errata`` in ``bench/studies/errata.py``, checks both the
printed and the corrected forms against Lagrange's equations).

**Branch signs.** The planar elements of a model "of the same structure" carry the sign product
``s_i s_j`` (and zero across branches); the transitions multiply by functions of ``psi`` only, so
the signs pass through unchanged.

**Removable singularities.** Printed lines divide by ``cos(phi_i - phi_j)``, ``cos phi_i`` and
``sin phi_i``, and the corrected ``k^l`` by ``l_j``. Each quotient is exact on the closed forms and is
computed without dividing:

* ``2D x_ij / cos(phi_i - phi_j)`` for ``x = a^phi, h^phi, lambda^l, d^l`` (elements whose only
  ``phi``-dependence is that factor) is the same element of the straightened model (every
  ``phi = 0``, so ``C = 1``): argument ``*_par``, e.g. ``a_phi_par = c_ij l_i l_j``;
* ``2D p^phi_i / cos phi_i`` times ``cos psi_i`` is ``2D p^phi_i`` with ``phi_i -> psi_i``, and
  likewise ``2D p^l_i sin psi_i / sin phi_i`` (the paper's own ``|_{phi -> psi}`` of the mu line);
* ``2D d^l_ij / l_j = -2D lambda^l_ij``.

So nothing divides and the 3D matrices are finite at every configuration.

Each function takes a namespace ``t`` (:func:`transition_inputs`) of the planar elements (``a_phi,
lam_phi, d_phi, h_phi, a_l, lam_l, d_l, h_l``), their ``*_par`` quotients, the lengths ``li, lj`` and
``ci, si, cj, sj`` (cos/sin of ``psi_i``, ``psi_j``): numpy arrays that broadcast, or sympy scalars of
one entry.
"""

from __future__ import annotations

from types import SimpleNamespace

from exo_bench.matrix_method.closed_forms import planar


#: The planar elements whose quotient by ``cos(phi_i - phi_j)`` the transitions use.
QUOTIENTS = {"a_phi_par": ("phi", "A"), "h_phi_par": ("phi", "H"), "lam_l_par": ("l", "Lambda"), "d_l_par": ("l", "D")}


def transition_inputs(planar_now, planar_straight, li, lj, ci, si, cj, sj) -> SimpleNamespace:
    """The namespace ``t`` of the transitions.

    ``planar_now[block][name]``: the planar elements at the configuration (``phi``, ``l``);
    ``planar_straight[block][name]``: the planar elements of the straightened model, all
    ``phi = 0`` (``C = 1, S = 0``). For ``x = a^phi, h^phi, lambda^l, d^l``, whose only dependence on
    ``phi`` is the factor ``cos(phi_i - phi_j)``, the straightened element is exactly the quotient
    ``x_ij / cos(phi_i - phi_j)``: this is how the divisions of (18) are removed.
    """
    t = SimpleNamespace(li=li, lj=lj, ci=ci, si=si, cj=cj, sj=sj)
    for block, fns in planar.PAIRS.items():
        for name, f in fns.items():
            setattr(t, f.__name__, planar_now[block][name])
    for attr, (block, name) in QUOTIENTS.items():
        setattr(t, attr, planar_straight[block][name])
    return t


# ------------------------------------------------------------------ phi block
def a_phi(t):
    """(18) a^phi: ``3D a^phi_ij = 2D a^phi_ij cos psi_i cos psi_j``.

    ``r_phi_i . l_j u_phi_j = l_i l_j c_i c_j C``. As printed.
    """
    return t.a_phi * t.ci * t.cj


def b_phi(t):
    """(18) b^phi: ``3D b^phi_ij = 2D a^l_ij l_i cos psi_i sin psi_j``.

    ``r_phi_i . l_j u_psi_j = l_i l_j c_i s_j S``, and ``2D a^l_ij = c_ij l_j S``. As printed.
    """
    return t.a_l * t.li * t.ci * t.sj


def lam_phi(t):
    """(18) lambda^phi: ``3D lambda^phi_ij = 2D lambda^phi_ij cos psi_i cos psi_j``.

    ``r_phi_i . u_j = -l_i c_i c_j S``. As printed.
    """
    return t.lam_phi * t.ci * t.cj


def d_phi(t):
    """(18) d^phi: ``3D d^phi_ij = 2D d^phi_ij cos psi_i cos psi_j``.

    ``r_phi_i . l_j u_phiphi_j = l_i l_j c_i c_j S``. As printed.
    """
    return t.d_phi * t.ci * t.cj


def e_phi(t):
    """(18) e^phi: ``3D e^phi_ij = 2D d^phi_ij cos psi_i cos psi_j``.

    ``r_phi_i . l_j u_psipsi_j = -l_i l_j u_phi_i . u_j = l_i l_j c_i c_j S``. As printed.
    """
    return t.d_phi * t.ci * t.cj


def g_phi(t):
    """(18) g^phi: ``3D g^phi_ij = -2D h^phi_ij l_j cos psi_i sin psi_j``.

    ``r_phi_i . l_j u_phipsi_j = -l_i l_j c_i s_j C``. As printed.
    """
    return -(t.h_phi * t.lj * t.ci * t.sj)


def h_phi(t):
    """(18) h^phi: ``3D h^phi_ij = 2D h^phi_ij cos psi_i cos psi_j``.

    ``r_phi_i . u_phi_j = l_i c_i c_j C``. As printed.
    """
    return t.h_phi * t.ci * t.cj


def k_phi(t):
    """(18) k^phi: ``3D k^phi_ij = -2D lambda^phi_ij cos psi_i sin psi_j``.

    ``r_phi_i . u_psi_j = l_i c_i s_j S``. As printed.
    """
    return -(t.lam_phi * t.ci * t.sj)


# ------------------------------------------------------------------ psi block
def a_psi(t):
    """(18) a^psi: ``3D a^psi_ij = -2D a^l_ij l_i cos psi_j sin psi_i``.

    ``r_psi_i . l_j u_phi_j = -l_i l_j s_i c_j S``. As printed.
    """
    return -(t.a_l * t.li * t.cj * t.si)


def b_psi(t):
    """(18) b^psi: ``3D b^psi_ij = 2D a^phi_ij (sin psi_i sin psi_j + cos psi_i cos psi_j / cos(phi_i - phi_j))``.

    ``r_psi_i . l_j u_psi_j = l_i l_j (s_i s_j C + c_i c_j)``. As printed; the quotient is
    ``a_phi_par = c_ij l_i l_j``.
    """
    return t.a_phi * t.si * t.sj + t.a_phi_par * t.ci * t.cj


def lam_psi(t):
    """(18) lambda^psi: ``3D lambda^psi_ij = 2D h^phi_ij (cos psi_i sin psi_j / cos(phi_i - phi_j) - cos psi_j sin psi_i)``.

    ``r_psi_i . u_j = l_i (c_i s_j - s_i c_j C)``. As printed; the quotient is ``h_phi_par = c_ij l_i``.
    """
    return t.h_phi_par * t.ci * t.sj - t.h_phi * t.cj * t.si


def d_psi(t):
    """(18) d^psi: ``3D d^psi_ij = 2D h^phi_ij l_j cos psi_j sin psi_i``.

    ``r_psi_i . l_j u_phiphi_j = l_i l_j s_i c_j C``. As printed.
    """
    return t.h_phi * t.lj * t.cj * t.si


def e_psi(t):
    """(18) e^psi: ``3D e^psi_ij = 2D h^phi_ij l_j (cos psi_j sin psi_i - cos psi_i sin psi_j / cos(phi_i - phi_j))``.

    ``r_psi_i . l_j u_psipsi_j = l_i l_j (s_i c_j C - c_i s_j)``. As printed.
    """
    return t.h_phi * t.lj * t.cj * t.si - t.h_phi_par * t.lj * t.ci * t.sj


def g_psi(t):
    """(18) g^psi: ``3D g^psi_ij = 2D d^phi_ij sin psi_i sin psi_j``.

    ``r_psi_i . l_j u_phipsi_j = l_i l_j s_i s_j S``. As printed.
    """
    return t.d_phi * t.si * t.sj


def h_psi(t):
    """(18) h^psi: ``3D h^psi_ij = 2D lambda^phi_ij sin psi_i cos psi_j``.

    ``r_psi_i . u_phi_j = -l_i s_i c_j S``. As printed.
    """
    return t.lam_phi * t.si * t.cj


def k_psi(t):
    """(18) k^psi: ``3D k^psi_ij = 2D h^phi_ij (sin psi_j sin psi_i + cos psi_i cos psi_j / cos(phi_i - phi_j))``.

    ``r_psi_i . u_psi_j = l_i (s_i s_j C + c_i c_j)``. Printed with the label ``2D k^psi``: a 2D model
    has no psi, the left side is the 3D element.
    """
    return t.h_phi * t.si * t.sj + t.h_phi_par * t.ci * t.cj


# -------------------------------------------------------------------- l block
def a_l(t):
    """(18) a^l: ``3D a^l_ij = 2D a^l_ij cos psi_i cos psi_j``.

    ``u_i . l_j u_phi_j = l_j c_i c_j S``. As printed.
    """
    return t.a_l * t.ci * t.cj


def b_l(t):
    """(18) b^l: ``3D b^l_ij = 2D d^l_ij (cos psi_i sin psi_j - sin psi_i cos psi_j / cos(phi_i - phi_j))``.

    ``u_i . l_j u_psi_j = l_j (s_i c_j - c_i s_j C)``, ``2D d^l_ij = -c_ij l_j C``. As printed; the
    quotient is ``d_l_par = -c_ij l_j``.
    """
    return t.d_l * t.ci * t.sj - t.d_l_par * t.si * t.cj


def lam_l(t):
    """(18) lambda^l: ``3D lambda^l_ij = 2D lambda^l_ij (cos psi_i cos psi_j + sin psi_i sin psi_j / cos(phi_i - phi_j))``.

    ``u_i . u_j = c_i c_j C + s_i s_j``. As printed; the quotient is ``lam_l_par = c_ij``.
    """
    return t.lam_l * t.ci * t.cj + t.lam_l_par * t.si * t.sj


def d_l(h_phi_3d_transposed):
    """(18) D_l: ``D_l = -(H_phi)^T`` (3D matrices): ``3D d^l_ij = -3D h^phi_ji``.

    ``u_i . l_j u_phiphi_j = -l_j c_i c_j C`` and ``3D h^phi_ji = c_ji l_j c_j c_i C``. As printed.
    """
    return -h_phi_3d_transposed


def e_l(t):
    """(18) e^l: ``3D e^l_ij = 2D d^l_ij (sin psi_i sin psi_j / cos(phi_i - phi_j) + cos psi_i cos psi_j)``.

    ``u_i . l_j u_psipsi_j = -l_j (c_i c_j C + s_i s_j)``. As printed.
    """
    return t.d_l_par * t.si * t.sj + t.d_l * t.ci * t.cj


def g_l(t):
    """(18) g^l: ``3D g^l_ij = -2D a^l_ij cos psi_i sin psi_j``.

    ``u_i . l_j u_phipsi_j = -l_j c_i s_j S``. Printed with ``3D a^l`` on the right, which adds a
    spurious factor ``cos psi_i cos psi_j``.
    """
    return -(t.a_l * t.ci * t.sj)


def h_l(t):
    """(18) h^l: ``3D h^l_ij = 2D h^l_ij cos psi_i cos psi_j``.

    ``u_i . u_phi_j = c_i c_j S``. As printed.
    """
    return t.h_l * t.ci * t.cj


def k_l(t):
    """(18) k^l: ``3D k^l_ij = 2D d^l_ij (cos psi_i sin psi_j - sin psi_i cos psi_j / cos(phi_i - phi_j)) / l_j``.

    ``u_i . u_psi_j = s_i c_j - c_i s_j C``. Printed with a leading minus sign (wrong). Without
    division: ``2D d^l_ij / l_j = -2D lambda^l_ij``, so ``k^l = lam_l_par s_i c_j - lam_l c_i s_j``.
    """
    return t.lam_l_par * t.si * t.cj - t.lam_l * t.ci * t.sj


# -------------------------------------------------------------------- gravity
def p_phi(nu_s, li, cpsi, spsi):
    """(18) p^phi: ``3D p^phi_i = 2D p^phi_i * 0``: gravity does no work on an azimuth. As printed."""
    return 0 * nu_s


def p_psi(nu_s, li, cpsi, spsi):
    """(18) p^psi: ``3D p^psi_i = 2D p^phi_i cos psi_i / cos phi_i``, i.e. ``2D p^phi_i`` with ``phi_i -> psi_i``.

    ``r_psi_i . up = l_i cos psi_i``: ``nu_i s_i l_i cos psi_i``. As printed; evaluated as the planar
    closed form at the angle ``psi_i``, so nothing divides by ``cos phi_i``.
    """
    return planar.p_phi(nu_s, li, cpsi, spsi)


def p_l(nu_s, li, cpsi, spsi):
    """(18) p^l: ``3D p^l_i = 2D p^l_i sin psi_i / sin phi_i``, i.e. ``2D p^l_i`` with ``phi_i -> psi_i``.

    ``u_i . up = sin psi_i``: ``nu_i s_i sin psi_i``. As printed; evaluated without dividing by
    ``sin phi_i``.
    """
    return planar.p_l(nu_s, li, cpsi, spsi)


#: The corrected transitions of eq. (18) by block and matrix name; ``D`` of block l is
#: :func:`d_l`, which takes the transposed 3D ``H_phi`` instead of the namespace.
PAIRS = {
    "phi": {"A": a_phi, "B": b_phi, "Lambda": lam_phi, "D": d_phi, "E": e_phi, "G": g_phi, "H": h_phi, "K": k_phi},
    "psi": {"A": a_psi, "B": b_psi, "Lambda": lam_psi, "D": d_psi, "E": e_psi, "G": g_psi, "H": h_psi, "K": k_psi},
    "l": {"A": a_l, "B": b_l, "Lambda": lam_l, "D": d_l, "E": e_l, "G": g_l, "H": h_l, "K": k_l},
}
GRAVITY = {"phi": p_phi, "psi": p_psi, "l": p_l}
