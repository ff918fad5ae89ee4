"""Eq. (5)/(17) in factored form: the element functions of method ``matrix-factored``, written once.

Every element of every matrix of eq. (5)/(17) is ``c_ij`` times a dot product of a vector of link
i and one of link j (:func:`exo_bench.matrix_method.numpy_kernels.matrix.inverse_dynamics` derives
it). Summing over the matrices of a block first,

    kappa_j = (what link j's rates do to d2/dt2(l_j u_j)),  f_i = sum_j c_ij kappa_j,
    tau_a,i = r_a,i . f_i + g P_a,i.

:func:`planar_kappa` / :func:`spatial_kappa` give ``kappa_j`` from link j's coordinates and rates,
:func:`planar_forces` / :func:`spatial_forces` give ``tau_a,i`` from ``f_i``. They take scalars
(the compiled kernels of :mod:`exo_bench.matrix_method.numba_kernels.factored`, one sample, one link
at a time; registered with numba there) or arrays (the numpy kernel, ``(n, samples)`` rows at once):
the same arithmetic, operation for operation.
"""

from __future__ import annotations

from typing import Any

#: A float or an array of floats: the element functions take either (numba: floats; numpy: arrays).
Num = Any


def planar_kappa(l: Num, w: Num, ld: Num, wdd: Num, ldd: Num, cf: Num, sf: Num) -> tuple[Num, Num]:
    """Eq. (5), factored: ``kappa_j`` of a planar link, its x and y components, from ``l_j, phi_j'``,
    ``l_j', phi_j'', l_j''`` and ``cos phi_j, sin phi_j``."""
    radial = ldd - l * w * w                  # along u: l'' and the centripetal l u_phiphi phi'^2
    tangent = 2.0 * ld * w + l * wdd          # along u_phi: l phi'' and 2 phi' l'
    return radial * cf - tangent * sf, radial * sf + tangent * cf


def planar_forces(l: Num, cf: Num, sf: Num, f0: Num, f1: Num, gnu: Num) -> tuple[Num, Num]:
    """Eq. (5), factored: ``(M_phi,i, F_i) = (r_phi . f + g P_phi, r_l . f + g P_l)`` from
    ``f_i = sum_j c_ij kappa_j`` and ``gnu = g nu_i s_i``."""
    return l * (cf * f1 - sf * f0 + gnu * cf), cf * f0 + sf * f1 + gnu * sf


def spatial_kappa(l: Num, w: Num, v: Num, ld: Num, wdd: Num, vdd: Num, ldd: Num,
                  cf: Num, sf: Num, cp: Num, sp: Num) -> tuple[Num, Num, Num]:
    """Eq. (17), factored: ``kappa_j`` of a spatial link, its x, y and z components, from ``l_j``,
    the rates ``phi_j', psi_j', l_j'``, ``phi_j'', psi_j'', l_j''`` and the cosines and sines of
    ``phi_j, psi_j``."""
    along_u = ldd - l * v * v                  # u l'' and l u_psipsi psi'^2 = -l u psi'^2
    along_psi = 2.0 * ld * v + l * vdd         # u_psi: l psi'' and 2 psi' l'
    # u_phiphi = -cos psi (cos phi, sin phi, 0), u_phipsi = -sin psi (-sin phi, cos phi, 0)
    horizontal = (along_u - l * w * w) * cp - along_psi * sp           # along (cos phi, sin phi, 0)
    azimuthal = (2.0 * ld * w + l * wdd) * cp - 2.0 * l * w * v * sp   # along (-sin phi, cos phi, 0)
    return horizontal * cf - azimuthal * sf, horizontal * sf + azimuthal * cf, along_u * sp + along_psi * cp


def spatial_forces(l: Num, cf: Num, sf: Num, cp: Num, sp: Num, f0: Num, f1: Num, f2: Num,
                   gnu: Num) -> tuple[Num, Num, Num]:
    """Eq. (17), factored: ``(M_phi,i, M_psi,i, F_i)`` from ``f_i = sum_j c_ij kappa_j`` and
    ``gnu = g nu_i s_i`` (``P_phi = 0``: gravity does no work along the azimuth)."""
    radial = cf * f0 + sf * f1
    vertical = f2 + gnu
    return (l * cp * (cf * f1 - sf * f0),                 # r_phi . f (P_phi = 0)
            l * (cp * vertical - sp * radial),            # r_psi . f + g P_psi
            cp * radial + sp * vertical)                  # r_l . f + g P_l
