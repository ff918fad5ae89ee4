"""Net joint loads from the point masses (Newton-Euler on each subtree), independent of any method.

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

import numpy as np

from exo_bench.models.mechanism.kinematics import place_down_the_tree, point_mass_positions, unit_vectors
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states, split


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
