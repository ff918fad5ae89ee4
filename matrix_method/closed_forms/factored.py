"""The element functions of method ``matrix-factored``: the physics of one link, written once.

Eq. (5)/(17) in factored form (the derivation is in :func:`exo_bench.matrix_method.numpy_kernels.matrix.inverse_dynamics`):

    kappa_j = what link j's rates do to d2/dt2(l_j u_j),  f_i = sum_j c_ij kappa_j,
    tau_a,i = r_a,i . f_i + g P_a,i.

:func:`kappa_2d`/:func:`kappa_3d` give ``kappa_j`` of one link from its length, rates and the
cosines and sines of its angles; :func:`forces_2d`/:func:`forces_3d` give the generalised forces of
link i from ``f_i``. They are plain arithmetic, so one definition serves every kernel: numba's
per-sample loops (:mod:`exo_bench.matrix_method.numba_kernels.factored`; registered with numba in
:mod:`exo_bench.matrix_method.numba_kernels.common`, which keys numba's cache on this file), the
kernel that vectorises across samples (:mod:`exo_bench.matrix_method.numba_kernels.simd`), the numpy
kernel and CasADi's (:mod:`exo_bench.matrix_method.numpy_kernels.matrix`, on ``(n, samples)`` rows or
symbols), and the flop count of the roofline (:mod:`exo_bench.bench.perf.roofline`, on counting
floats). Each takes scalars or arrays alike.
"""

from __future__ import annotations


def kappa_2d(l, w, ld, wdd, ldd, cf, sf):
    """Eq. (5), factored: ``kappa_j`` of a planar link (x, y) from ``l, phi', l', phi'', l''`` and
    ``cos phi, sin phi``."""
    radial = ldd - l * w * w  # along u: l'' and the centripetal l u_phiphi phi'^2
    tangent = 2.0 * ld * w + l * wdd  # along u_phi: l phi'' and 2 phi' l'
    return radial * cf - tangent * sf, radial * sf + tangent * cf


def forces_2d(l, cf, sf, f0, f1, gnu):
    """Eq. (5), factored: ``(M_phi, F)`` of planar link i from ``f_i = (f0, f1)`` and ``g nu_i s_i``."""
    return l * (cf * f1 - sf * f0 + gnu * cf), cf * f0 + sf * f1 + gnu * sf  # r_phi . f + g P_phi, r_l . f + g P_l


def kappa_3d(l, w, v, ld, wdd, vdd, ldd, cf, sf, cp, sp):
    """Eq. (17), factored: ``kappa_j`` of a spatial link (x, y, z) from ``l``, the rates
    ``phi', psi', l'``, ``phi'', psi'', l''`` and the cosines and sines of ``phi`` and ``psi``."""
    along_u = ldd - l * v * v  # u l'' and l u_psipsi psi'^2 = -l u psi'^2
    along_psi = 2.0 * ld * v + l * vdd  # u_psi: l psi'' and 2 psi' l'
    # u_phiphi = -cos psi (cos phi, sin phi, 0), u_phipsi = -sin psi (-sin phi, cos phi, 0)
    horizontal = (along_u - l * w * w) * cp - along_psi * sp  # along (cos phi, sin phi, 0)
    azimuthal = (2.0 * ld * w + l * wdd) * cp - 2.0 * l * w * v * sp  # along (-sin phi, cos phi, 0)
    return horizontal * cf - azimuthal * sf, horizontal * sf + azimuthal * cf, along_u * sp + along_psi * cp


def forces_3d(l, cf, sf, cp, sp, f0, f1, f2, gnu):
    """Eq. (17), factored: ``(M_phi, M_psi, F)`` of spatial link i from ``f_i = (f0, f1, f2)`` and
    ``g nu_i s_i``."""
    radial = cf * f0 + sf * f1
    vertical = f2 + gnu
    return (
        l * cp * (cf * f1 - sf * f0),  # r_phi . f (P_phi = 0)
        l * (cp * vertical - sp * radial),  # r_psi . f + g P_psi
        cp * radial + sp * vertical,
    )  # r_l . f + g P_l
