"""Point-mass kinematics and energies, computed directly from the geometry.

This module knows nothing of the equations of motion: it places the point
masses (eq. 7 and its planar analogue), differentiates their positions, and sums
``T = 1/2 sum m v^2`` and ``Pi = g sum m h``. The tests use it as an oracle
(power balance ``d(T + Pi)/dt = tau . qd``) for every dynamics implementation.

Arrays are batch-first: ``q`` is ``(samples, dof)``; positions are
``(samples, n, 3, dim)`` indexed by link, mass ``beta = 0, 1, 2`` (start,
middle, end) and Cartesian axis. Gravity acts along ``-y`` in 2D and ``-z``
in 3D.
"""

from __future__ import annotations

from typing import overload

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import split


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
