"""The rod elements of the Newton-Euler method: one rod's map ``q_i -> r_i`` and its derivatives.

Rod ``i`` has the vector ``r_i = s_i l_i u_i`` from its start to its end, with the unit vector
``u_i = (cos phi, sin phi)`` in 2D and ``(cos psi cos phi, cos psi sin phi, sin psi)`` in 3D (eq. 7)
and the branch sign ``s_i``. With the orthonormal frame ``e_phi = (-sin phi, cos phi, 0)``,
``e_psi = (-sin psi cos phi, -sin psi sin phi, cos psi)``, ``u`` (2D: ``e_phi = (-sin phi,
cos phi)``, ``u``), the rod's block of ``J = dr/dq`` is

    J_i = s_i [e_phi, e_psi, u] diag(l cos psi, l, 1)        (2D: s_i [e_phi, u] diag(l, 1)),

so ``J_i^T F = s_i (l cos psi e_phi.F, l e_psi.F, u.F)`` and ``J_i^-1 v = s_i (e_phi.v / (l cos psi),
e_psi.v / l, u.v)``: singular at ``l = 0`` and, in 3D, at ``cos psi = 0`` (a vertical rod).

Every function takes the cosines and sines already computed and does arithmetic only, so the
same function runs on floats inside the numba kernels (:mod:`exo_bench.models.newton_euler.compiled`
registers them with ``register_jitable``) and on ``(samples,)`` arrays in the numpy reference
(:mod:`exo_bench.models.newton_euler.passes`): nothing physical is written twice. All are **unsigned**
(``s_i = 1``); the callers multiply by ``s_i``.
"""

from __future__ import annotations


def rod_acceleration_2d(cf, sf, l, w, ld, wdd, ldd):
    """``d2/dt2 (l u)`` of a planar rod: ``J q'' + J' q'`` (unsigned), as ``(x, y)``.

    ``(l u)'' = l'' u + 2 l' phi' e_phi + l phi'' e_phi - l phi'^2 u``."""
    radial = ldd - l * w * w  # along u: l'' and the centripetal -l phi'^2
    tangent = 2.0 * ld * w + l * wdd  # along e_phi: l phi'' and 2 phi' l'
    return radial * cf - tangent * sf, radial * sf + tangent * cf


def rod_acceleration_3d(cf, sf, cp, sp, l, w, v, ld, wdd, vdd, ldd):
    """``d2/dt2 (l u)`` of a spatial rod: ``J q'' + J' q'`` (unsigned), as ``(x, y, z)``.

    With ``u_phi = cos psi e_phi``, ``u_psi = e_psi``, ``u_phiphi = -cos psi (cos phi, sin phi, 0)``,
    ``u_phipsi = -sin psi e_phi``, ``u_psipsi = -u``: ``(l u)'' = l'' u + 2 l' (u_phi phi' + u_psi psi')
    + l (u_phi phi'' + u_psi psi'' + u_phiphi phi'^2 + 2 u_phipsi phi' psi' + u_psipsi psi'^2)``."""
    along_u = ldd - l * v * v  # u l'' and l u_psipsi psi'^2 = -l u psi'^2
    along_psi = 2.0 * ld * v + l * vdd  # e_psi: l psi'' and 2 psi' l'
    horizontal = (along_u - l * w * w) * cp - along_psi * sp  # along (cos phi, sin phi, 0)
    azimuthal = (2.0 * ld * w + l * wdd) * cp - 2.0 * l * w * v * sp  # along e_phi
    return (horizontal * cf - azimuthal * sf, horizontal * sf + azimuthal * cf, along_u * sp + along_psi * cp)


def project_2d(cf, sf, l, fx, fy):
    """``J^T F`` of a planar rod (unsigned): the generalised forces ``(M_phi, F_l)`` of a force
    ``F`` conjugate to ``r``."""
    return l * (cf * fy - sf * fx), cf * fx + sf * fy


def project_3d(cf, sf, cp, sp, l, fx, fy, fz):
    """``J^T F`` of a spatial rod (unsigned): ``(M_phi, M_psi, F_l)`` of a force ``F`` conjugate to ``r``."""
    radial = cf * fx + sf * fy  # along (cos phi, sin phi, 0)
    return l * cp * (cf * fy - sf * fx), l * (cp * fz - sp * radial), cp * radial + sp * fz


def unproject_2d(cf, sf, l, tw, tl):
    """``J^-T tau`` of a planar rod (unsigned): the force ``F`` with ``J^T F = (tw, tl)``; divides
    by ``l`` (singular at ``l = 0``)."""
    a = tw / l
    return tl * cf - a * sf, tl * sf + a * cf


def unproject_3d(cf, sf, cp, sp, l, tw, tv, tl):
    """``J^-T tau`` of a spatial rod (unsigned): ``F = e_phi tw / (l cos psi) + e_psi tv / l + u tl``;
    singular at ``l = 0`` and ``cos psi = 0``."""
    a, b = tw / (l * cp), tv / l
    horizontal = tl * cp - b * sp  # along (cos phi, sin phi, 0)
    return horizontal * cf - a * sf, horizontal * sf + a * cf, tl * sp + b * cp


def rates_2d(cf, sf, l, vx, vy):
    """``J^-1 v`` of a planar rod (unsigned): the coordinate rates ``(phi', l')`` of a rod-vector
    rate ``v``."""
    return (cf * vy - sf * vx) / l, cf * vx + sf * vy


def rates_3d(cf, sf, cp, sp, l, vx, vy, vz):
    """``J^-1 v`` of a spatial rod (unsigned): ``(phi', psi', l')`` of a rod-vector rate ``v``."""
    radial = cf * vx + sf * vy
    return (cf * vy - sf * vx) / (l * cp), (cp * vz - sp * radial) / l, cp * radial + sp * vz


def rod_force(zeta, eta, a, kappa, d):
    """``F_k = eta_k (A_k + g up) + zeta_k kappa_k + D_k``: one component of the force conjugate to
    ``r_k`` (eq. 6's aggregates), from the start point's acceleration with gravity ``a``, the rod's
    ``kappa = r_k''`` and the subtree sum ``d`` (:mod:`exo_bench.models.newton_euler.passes`)."""
    return eta * a + zeta * kappa + d


def subtree_share(theta, eta, a, kappa, d):
    """``theta_k (A_k + g up) + eta_k kappa_k + D_k``: one component of what link ``k`` and its subtree
    add to its parent's subtree sum ``D_parent``."""
    return theta * a + eta * kappa + d


ELEMENTS = (
    rod_acceleration_2d,
    rod_acceleration_3d,
    project_2d,
    project_3d,
    unproject_2d,
    unproject_3d,
    rates_2d,
    rates_3d,
    rod_force,
    subtree_share,
)
