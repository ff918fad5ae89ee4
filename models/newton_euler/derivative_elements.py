"""Derivatives of the rod elements (:mod:`exo_bench.models.mechanism.rod_elements`) with respect to one
rod's own coordinates: what the analytic derivatives of inverse dynamics need per rod
(:mod:`exo_bench.models.newton_euler.derivatives`).

Like the elements, every function takes the cosines and sines already computed, does arithmetic only
(the same function runs on floats in numba via ``register_jitable`` and on ``(samples,)`` arrays,
real or complex, in numpy) and is **unsigned** (``s_i = 1``; the callers multiply by ``s_i``).

**Reuse instead of new physics.** The azimuth ``phi`` turns a rod about the vertical: ``l u =
R(phi) (l u)|_{phi=0}``, so ``d (l u)''/d phi = e_up x (l u)''`` (2D: a quarter turn, ``(-a_y, a_x)``) and,
with ``J = R J_0``, ``d (J^T F)/d phi = J^T (F x e_up)`` (``F x e_up = (F_y, -F_x, 0)``; 2D ``(F_y,
-F_x)``): the element itself, turned. The elevation ``psi`` enters every element as a polynomial of
degree one in ``(cos psi, sin psi)`` jointly (each term holds exactly one of the two): ``f = A cos psi +
B sin psi``, so ``df/dpsi = f(-sin psi, cos psi)``, the element at ``psi + pi/2``. The acceleration
``(l u)''`` is linear in ``(l, l', l'')`` jointly, so its derivative in ``l`` is the element at ``l = 1,
l' = l'' = 0``, in ``l'`` the element at ``l = 0, l' = 1, l'' = 0`` (``2 u'``), and its columns in the
accelerations ``q''`` (the Jacobian ``J = d(l u)/dq``) the element at zero rates and a unit
acceleration. ``J^T F`` is linear in ``l`` except its last component (``u.F``), so its derivative in
``l`` is the element at ``l = 1`` with that component zero. Only the derivatives in the angle rates
``phi'`` and ``psi'`` are written out here (:func:`acceleration_by_rates_2d`,
:func:`acceleration_by_rates_3d`); tests/test_derivatives_analytic.py holds every function to
complex-step derivatives of the elements.

Vectors come as flat tuples: ``(x, y)`` per column in 2D, ``(x, y, z)`` in 3D, columns in the order
``phi, l`` (2D) or ``phi, psi, l`` (3D).
"""

from __future__ import annotations

from exo_bench.models.mechanism.rod_elements import (
    project_2d,
    project_3d,
    rod_acceleration_2d,
    rod_acceleration_3d,
)


def jacobian_2d(cf, sf, l):
    """``J = d(l u)/d(phi, l)`` of a planar rod: columns ``l e_phi`` and ``u``, as ``(x, y)`` each."""
    a0, a1 = rod_acceleration_2d(cf, sf, l, 0.0, 0.0, 1.0, 0.0)
    b0, b1 = rod_acceleration_2d(cf, sf, l, 0.0, 0.0, 0.0, 1.0)
    return a0, a1, b0, b1


def jacobian_3d(cf, sf, cp, sp, l):
    """``J = d(l u)/d(phi, psi, l)`` of a spatial rod: columns ``l cos psi e_phi``, ``l e_psi``, ``u``."""
    a0, a1, a2 = rod_acceleration_3d(cf, sf, cp, sp, l, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
    b0, b1, b2 = rod_acceleration_3d(cf, sf, cp, sp, l, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0)
    c0, c1, c2 = rod_acceleration_3d(cf, sf, cp, sp, l, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    return a0, a1, a2, b0, b1, b2, c0, c1, c2


def acceleration_by_q_2d(cf, sf, l, w, ld, wdd, ldd):
    """``d (l u)'' / d(phi, l)`` of a planar rod at its rates ``w = phi'``, ``ld = l'`` and accelerations."""
    a0, a1 = rod_acceleration_2d(cf, sf, l, w, ld, wdd, ldd)
    b0, b1 = rod_acceleration_2d(cf, sf, 1.0, w, 0.0, wdd, 0.0)
    return -a1, a0, b0, b1


def acceleration_by_q_3d(cf, sf, cp, sp, l, w, v, ld, wdd, vdd, ldd):
    """``d (l u)'' / d(phi, psi, l)`` of a spatial rod (``v = psi'``)."""
    a0, a1, a2 = rod_acceleration_3d(cf, sf, cp, sp, l, w, v, ld, wdd, vdd, ldd)
    b0, b1, b2 = rod_acceleration_3d(cf, sf, -sp, cp, l, w, v, ld, wdd, vdd, ldd)
    c0, c1, c2 = rod_acceleration_3d(cf, sf, cp, sp, 1.0, w, v, 0.0, wdd, vdd, 0.0)
    return -a1, a0, 0.0 * a2, b0, b1, b2, c0, c1, c2


def acceleration_by_rates_2d(cf, sf, l, w, ld):
    """``d (l u)'' / d(phi', l')`` of a planar rod: ``2 (l phi' (-u) + l' e_phi)`` and ``2 phi' e_phi``.

    From ``(l u)'' = (l'' - l phi'^2) u + (2 l' phi' + l phi'') e_phi``."""
    radial, tangent = -2.0 * l * w, 2.0 * ld  # d/dphi' of the two brackets
    b0, b1 = rod_acceleration_2d(cf, sf, 0.0, w, 1.0, 0.0, 0.0)
    return radial * cf - tangent * sf, radial * sf + tangent * cf, b0, b1


def acceleration_by_rates_3d(cf, sf, cp, sp, l, w, v, ld):
    """``d (l u)'' / d(phi', psi', l')`` of a spatial rod, the brackets of
    :func:`exo_bench.models.mechanism.rod_elements.rod_acceleration_3d` differentiated (``horizontal``
    along ``(cos phi, sin phi, 0)``, ``azimuthal`` along ``e_phi``, ``vertical`` along ``z``)."""
    # d/dphi': horizontal -2 l phi' cos psi, azimuthal 2 (l' cos psi - l psi' sin psi), vertical 0
    h, az = -2.0 * l * w * cp, 2.0 * (ld * cp - l * v * sp)
    # d/dpsi': along_u -2 l psi', along_psi 2 l'
    du, dpsi = -2.0 * l * v, 2.0 * ld
    h2, az2 = du * cp - dpsi * sp, -2.0 * l * w * sp
    c0, c1, c2 = rod_acceleration_3d(cf, sf, cp, sp, 0.0, w, v, 1.0, 0.0, 0.0, 0.0)
    return (
        h * cf - az * sf,
        h * sf + az * cf,
        0.0 * h,
        h2 * cf - az2 * sf,
        h2 * sf + az2 * cf,
        du * sp + dpsi * cp,
        c0,
        c1,
        c2,
    )


def projection_by_q_2d(cf, sf, l, fx, fy):
    """``d (J^T F) / d(phi, l)`` of a planar rod at fixed ``F``: column ``phi`` then column ``l``, each
    ``(M_phi, F_l)``."""
    a0, a1 = project_2d(cf, sf, l, fy, -fx)
    b0, _ = project_2d(cf, sf, 1.0, fx, fy)
    return a0, a1, b0, 0.0 * b0


def projection_by_q_3d(cf, sf, cp, sp, l, fx, fy, fz):
    """``d (J^T F) / d(phi, psi, l)`` of a spatial rod at fixed ``F``: three columns of ``(M_phi, M_psi, F_l)``."""
    a0, a1, a2 = project_3d(cf, sf, cp, sp, l, fy, -fx, 0.0 * fz)
    b0, b1, b2 = project_3d(cf, sf, -sp, cp, l, fx, fy, fz)
    c0, c1, _ = project_3d(cf, sf, cp, sp, 1.0, fx, fy, fz)
    return a0, a1, a2, b0, b1, b2, c0, c1, 0.0 * c0


DERIVATIVE_ELEMENTS = (
    jacobian_2d,
    jacobian_3d,
    acceleration_by_q_2d,
    acceleration_by_q_3d,
    acceleration_by_rates_2d,
    acceleration_by_rates_3d,
    projection_by_q_2d,
    projection_by_q_3d,
)
