"""Point-mass kinematics, energies and net joint loads, computed directly from the geometry.

This module knows nothing of the equations of motion: it places the point
masses (eq. 7 and its planar analogue), differentiates their positions, and sums
``T = 1/2 sum m v^2`` and ``Pi = g sum m h``. The tests use it as an oracle
(power balance ``d(T + Pi)/dt = tau . qd``) for every dynamics implementation.

Arrays are batch-first: ``q`` is ``(samples, dof)``; positions are
``(samples, n, 3, dim)`` indexed by link, mass ``beta = 0, 1, 2`` (start,
middle, end) and Cartesian axis. Gravity acts along ``-y`` in 2D and ``-z``
in 3D.

**Net joint loads** from the point masses (Newton-Euler on each subtree), independent of any method.

The **net joint moment** at joint k (the start point ``r_k`` of link k, where it hangs from its
parent or from the support point O) is the moment the parent side must exert on the subtree of
link k, about ``r_k``, in world axes::

    M_k = sum_{masses j of the subtree} (p_j - r_k) x m_j (a_j - g)

and the **net joint force** is ``F_k = sum m_j (a_j - g)``. This is what gait analysis calls the
net (intersegmental) joint moment and force; every point mass moves by eq. (7), so the
accelerations are exact (:func:`point_mass_accelerations`).

**How they relate to Pinocchio's joint torques.** ``tau_joint = G^-T tau``
(:func:`exo_bench.models.engines.pinocchio_backend.joint_torques`) is the generalised force of Pinocchio's joint
coordinates ``[phi_k - phi_parent, psi_k, l_k]``. Its azimuth rows are the vertical component
``M_k . e_z`` (a relative azimuth turns the whole subtree about the vertical through ``r_k``). Its
elevation rows are not the physical moment about the elevation axis when link k has children:
``psi_k`` is an *absolute* elevation, so turning it keeps every child's elevation, and the row is
the moment at ``r_k`` minus the children's moments at their joints about the same axis (the 3D
URDF's "undo" mimic joints). Only for a leaf link is ``tau_joint[psi_k]`` the moment in the joint.
``tests/test_joint_loads.py`` checks both statements against Pinocchio.

Arrays are batch-first: accelerations ``(S, n, 3, dim)`` like
:func:`exo_bench.models.mechanism.kinematics.point_mass_positions`; moments ``(S, n, 3)`` in 3D and ``(S, n)`` (the
z component) in 2D; forces ``(S, n, dim)``.
"""

from __future__ import annotations

from typing import overload

import numpy as np
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states, split


def unit_vectors(mech: Mechanism, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Rod directions ``u`` and their partials ``du/dphi``, ``du/dpsi`` (None in 2D), each ``(S, n, dim)``.

    2D: ``u = (cos phi, sin phi)``; 3D (eq. 7): ``u = (cos psi cos phi, cos psi sin phi, sin psi)``.
    """
    phi, psi, _ = split(mech, q)
    c, s = np.cos(phi), np.sin(phi)
    if psi is None:  # 2D
        u = np.stack([c, s], axis=-1)
        u_phi = np.stack([-s, c], axis=-1)
        return u, u_phi, None
    cp, sp = np.cos(psi), np.sin(psi)
    u = np.stack([cp * c, cp * s, sp], axis=-1)
    u_phi = np.stack([-cp * s, cp * c, np.zeros_like(c)], axis=-1)
    u_psi = np.stack([-sp * c, -sp * s, cp], axis=-1)
    return u, u_phi, u_psi


@overload
def _rod_vectors(mech: Mechanism, q: np.ndarray, qd: None) -> tuple[np.ndarray, None]: ...
@overload
def _rod_vectors(mech: Mechanism, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...
def _rod_vectors(mech: Mechanism, q: np.ndarray, qd: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """``w_i = sign_i l_i u_i`` (start of link i to its end) and its time derivative."""
    _, _, l = split(mech, q)
    u, u_phi, u_psi = unit_vectors(mech, q)
    s = mech.sign_array[None, :, None]
    w = s * l[..., None] * u
    if qd is None:
        return w, None
    phid, psid, ld = split(mech, qd)
    udot = u_phi * phid[..., None]
    if u_psi is not None and psid is not None:  # 3D: both or neither
        udot = udot + u_psi * psid[..., None]
    wd = s * (ld[..., None] * u + l[..., None] * udot)
    return w, wd


def place_down_the_tree(mech: Mechanism, w: np.ndarray) -> np.ndarray:
    """Point masses from rod vectors, ``(S, n, 3, dim)``: mass beta of link i sits at
    ``end(parent) + n_beta w_i``. Linear in ``w``, so it places positions from ``w``, velocities from
    ``w'`` and accelerations from ``w''`` alike."""
    S, n, d = w.shape
    start = np.zeros((S, n, d))
    ends = np.zeros((S, n, d))
    for i in range(n):  # parents come first, so one pass suffices
        p = mech.parent[i]
        start[:, i] = ends[:, p] if p >= 0 else 0.0
        ends[:, i] = start[:, i] + w[:, i]
    return start[:, :, None, :] + mech.fractions[None, :, :, None] * w[:, :, None, :]


def point_mass_positions(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """World positions of every point mass, ``(S, n, 3, dim)``."""
    w, _ = _rod_vectors(mech, q, None)
    return place_down_the_tree(mech, w)


def point_mass_velocities(mech: Mechanism, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """World velocities of every point mass, ``(S, n, 3, dim)`` (the same sums, differentiated)."""
    _, wd = _rod_vectors(mech, q, qd)
    return place_down_the_tree(mech, wd)


def kinetic_energy(mech: Mechanism, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """``T = 1/2 sum_i sum_beta m_ibeta |v_ibeta|^2``, shape ``(S,)``."""
    v = point_mass_velocities(mech, q, qd)
    return 0.5 * np.einsum("ib,sibk,sibk->s", mech.mass_array, v, v)


def potential_energy(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """``Pi = g sum m h`` with h the last Cartesian coordinate, shape ``(S,)``."""
    r = point_mass_positions(mech, q)
    return mech.g * np.einsum("ib,sib->s", mech.mass_array, r[..., -1])


def rod_end_points(mech: Mechanism, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end point of every rod, each ``(S, n, dim)``, for drawing stick figures."""
    r = point_mass_positions(mech, q)
    return r[:, :, 0], r[:, :, 2]


def total_energy(mech: Mechanism, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """``T + Pi`` per sample, ``(S,)``."""
    return kinetic_energy(mech, q, qd) + potential_energy(mech, q)


# Sixth-order central difference for the first derivative, offsets -3..3.
_FD6 = np.array([-1 / 60, 3 / 20, -3 / 4, 0.0, 3 / 4, -3 / 20, 1 / 60])


def energy_rate(mech: Mechanism, motion_of_t, t: np.ndarray, h: float = 1e-3) -> np.ndarray:
    """``d(T + Pi)/dt`` along a motion, by a sixth-order central difference of the energy
    computed from the point masses' positions and velocities. ``motion_of_t(t)`` returns a
    :class:`exo_bench.models.gait.motion.Motion`. The truncation error is ``O(h^6)``; with ``h = 1e-3`` and a
    smooth motion it sits far below 1e-8 relative."""
    t = np.asarray(t, dtype=float)
    rate = np.zeros_like(t)
    for c, k in zip(_FD6, range(-3, 4)):
        if c:
            m = motion_of_t(t + k * h)
            rate += c * total_energy(mech, m.q, m.qd)
    return rate / h


def _rod_accelerations(mech: Mechanism, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """``d^2/dt^2 (sign_i l_i u_i)``, ``(S, n, dim)``: ``l'' u + 2 l' u' + l u''``."""
    phi, psi, l = split(mech, q)
    phid, psid, ld = split(mech, qd)
    phidd, psidd, ldd = split(mech, qdd)
    u, u_phi, u_psi = unit_vectors(mech, q)
    if mech.dim == 2:
        ud = u_phi * phid[..., None]
        udd = u_phi * phidd[..., None] - u * (phid**2)[..., None]
    else:
        assert psi is not None and psid is not None and psidd is not None and u_psi is not None  # 3D
        c, s = np.cos(phi), np.sin(phi)
        sp = np.sin(psi)
        zero = np.zeros_like(c)
        u_phiphi = np.stack([-u[..., 0], -u[..., 1], zero], axis=-1)  # d2u/dphi2
        u_phipsi = np.stack([sp * s, -sp * c, zero], axis=-1)  # d2u/dphi dpsi
        ud = u_phi * phid[..., None] + u_psi * psid[..., None]
        udd = (
            u_phi * phidd[..., None]
            + u_psi * psidd[..., None]
            + u_phiphi * (phid**2)[..., None]
            + 2.0 * u_phipsi * (phid * psid)[..., None]
            - u * (psid**2)[..., None]
        )  # d2u/dpsi2 = -u
    acc = ldd[..., None] * u + 2.0 * ld[..., None] * ud + l[..., None] * udd
    return mech.sign_array[None, :, None] * acc


def point_mass_accelerations(mech: Mechanism, q, qd, qdd) -> np.ndarray:
    """World accelerations of every point mass, ``(S, n, 3, dim)``, exact from eq. (7)."""
    q, qd, qdd = as_states(mech, q, qd, qdd)
    return place_down_the_tree(mech, _rod_accelerations(mech, q, qd, qdd))


def subtree(mech: Mechanism, k: int) -> tuple[int, ...]:
    """Link ``k`` and every link that hangs from it, directly or not (0-based, ``k`` first)."""
    out = [k]
    for c in mech.children[k]:
        out.extend(subtree(mech, c))
    return tuple(out)


def gravity_vector(mech: Mechanism) -> np.ndarray:
    """``g`` as a vector: ``-g e_y`` in 2D, ``-g e_z`` in 3D."""
    g = np.zeros(mech.dim)
    g[-1] = -mech.g
    return g


def net_joint_loads(mech: Mechanism, q, qd, qdd) -> tuple[np.ndarray, np.ndarray]:
    """Net joint moments and forces at the start of every link: ``(M, F)``.

    ``M`` is ``(S, n, 3)`` in 3D (world axes) and ``(S, n)`` in 2D (the moment about z); ``F`` is
    ``(S, n, dim)``. Both act from the parent side on the subtree of the link (see the module text).
    """
    q, qd, qdd = as_states(mech, q, qd, qdd)
    P = point_mass_positions(mech, q)
    A = point_mass_accelerations(mech, q, qd, qdd)
    m = mech.mass_array[None, :, :, None]
    f = m * (A - gravity_vector(mech))  # (S, n, 3, dim): m (a - g) of every mass
    S, n = q.shape[0], mech.nlinks
    M = np.zeros((S, n, 3)) if mech.dim == 3 else np.zeros((S, n))
    F = np.zeros((S, n, mech.dim))
    for k in range(n):
        links = list(subtree(mech, k))
        r = P[:, k, 0][:, None, None, :]  # the joint: start of link k
        arm = P[:, links] - r
        fk = f[:, links]
        if mech.dim == 3:
            M[:, k] = np.cross(arm, fk).sum(axis=(1, 2))
        else:
            M[:, k] = (arm[..., 0] * fk[..., 1] - arm[..., 1] * fk[..., 0]).sum(axis=(1, 2))
        F[:, k] = fk.sum(axis=(1, 2))
    return M, F


def sagittal_moments(mech: Mechanism, M: np.ndarray) -> np.ndarray:
    """The component of net joint moments ``M`` in the sagittal plane, ``(S, n)``.

    The sagittal plane is x-z in 3D (x forward, z up) and the model's plane in 2D. A moment that
    turns a rod from +x towards up is positive, as in Winter's tables (counter-clockwise with the
    subject walking to the right): about ``-e_y`` in 3D, about ``+e_z`` in 2D.
    """
    return -M[..., 1] if mech.dim == 3 else M


def moment_components(mech: Mechanism, M: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
    """The components of net joint moments ``M`` (:func:`net_joint_loads`) that the scene reports and
    figures show, each ``(name, sign convention, (S, n) array)``: the sagittal one
    (:func:`sagittal_moments`), and in 3D the frontal (about +x, forward) and transverse (about +z, up)
    ones, right-handed. The figures and the report's Plausibility table both read them from here."""
    out = [("sagittal", "positive turns a rod from forward (+x) towards up, Winter's sign", sagittal_moments(mech, M))]
    if mech.dim == 3:
        out += [
            ("frontal", "about +x (forward), right-handed", M[..., 0]),
            ("transverse", "about +z (up), right-handed", M[..., 2]),
        ]
    return out


__all__ = [
    "gravity_vector",
    "moment_components",
    "net_joint_loads",
    "point_mass_accelerations",
    "sagittal_moments",
    "subtree",
]
