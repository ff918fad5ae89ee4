"""Pinocchio backend against oracles that do not come from it: hand-derived one-link equations,
eq. (4), the kinetic energy of the point masses, and power balance on random trees."""

import numpy as np
import pytest
from conftest import K, POWER_BALANCE_TOL, assert_close, assert_forces_agree, mass_matrix_scale, power_balance_residual

from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.mechanism.kinematics import kinetic_energy, point_mass_positions
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import fig1, fig2a, fig2b, random_tree


def _one_link_aggregates(m):
    (m0, m1, m2), n = m.masses[0], m.n[0]
    return m1 * n**2 + m2, m1 * n + m2  # zeta, eta (m0 sits at the hinge)


def test_one_link_planar_is_eq2(rel):
    m = fig1(2)
    zeta, eta, g = *_one_link_aggregates(m), m.g
    q, qd, qdd = random_states(m, 50, 1)
    (phi, l), (w, ld), (wdd, ldd) = q.T, qd.T, qdd.T
    M = l**2 * zeta * wdd + g * l * eta * np.cos(phi) + 2 * l * zeta * ld * w
    F = -l * zeta * w**2 + g * eta * np.sin(phi) + zeta * ldd
    assert_forces_agree(pb.inverse_dynamics(m, q, qd, qdd), np.stack([M, F], -1), m, q, qd, qdd)


def test_one_link_spatial_is_our_derivation_from_T_and_Pi(rel):
    """From T = zeta/2 (l'^2 + l^2 (phi'^2 cos^2 psi + psi'^2)) and Pi = g eta l sin psi (eqs. 11-12):
    the psi equation has 2 zeta l l' psi', where the printed (14) has phi' (a misprint)."""
    m = fig1(3)
    zeta, eta, g = *_one_link_aggregates(m), m.g
    q, qd, qdd = random_states(m, 50, 2)
    (phi, psi, l), (w, v, ld), (wdd, vdd, ldd) = q.T, qd.T, qdd.T
    C, S = np.cos(psi), np.sin(psi)
    M_phi = zeta * l**2 * C**2 * wdd + 2 * zeta * l * C**2 * ld * w - 2 * zeta * l**2 * C * S * w * v
    M_psi = zeta * l**2 * vdd + zeta * l**2 * C * S * w**2 + 2 * zeta * l * ld * v + g * eta * l * C
    F = zeta * ldd - zeta * l * C**2 * w**2 - zeta * l * v**2 + g * eta * S
    tau = pb.inverse_dynamics(m, q, qd, qdd)
    assert_forces_agree(tau, np.stack([M_phi, M_psi, F], -1), m, q, qd, qdd)
    printed_14 = M_psi - 2 * zeta * l * ld * v + 2 * zeta * l * ld * w
    assert rel(tau[:, 1], printed_14) > 1e-3


def _eq4(m, q, qd, qdd, sigma):
    """Eq. (4) with upper (sigma = +1, Fig. 2a) or lower (sigma = -1, Fig. 2b) signs, as printed."""
    (m10, m11, m12), (m20, m21, m22) = m.masses
    n1, n2 = m.n
    z1, z2 = m11 * n1**2 + m12, m21 * n2**2 + m22
    e1, e2 = m11 * n1 + m12, m21 * n2 + m22
    t2 = m20 + m21 + m22
    g, s = m.g, sigma
    (p1, p2, l1, l2), (w1, w2, d1, d2), (a1, a2, b1, b2) = q.T, qd.T, qdd.T
    C1, S1, C2, S2 = np.cos(p1), np.sin(p1), np.cos(p2), np.sin(p2)
    C12, S12 = np.cos(p1 - p2), np.sin(p1 - p2)
    r1 = (
        (z1 + t2) * l1**2 * a1
        + s * l1 * l2 * e2 * C12 * a2
        + s * l1 * l2 * e2 * S12 * w2**2
        + (e1 + t2) * g * l1 * C1
        + 2 * (z1 + t2) * l1 * d1 * w1
        + s * 2 * l1 * e2 * C12 * d2 * w2
        - s * l1 * e2 * S12 * b2
    )
    r2 = (
        s * l1 * l2 * e2 * C12 * a1
        + z2 * l2**2 * a2
        - s * l1 * l2 * e2 * S12 * w1**2
        + s * e2 * g * l2 * C2
        + s * 2 * l2 * e2 * C12 * d1 * w1
        + 2 * z2 * l2 * d2 * w2
        + s * l2 * e2 * S12 * b1
    )
    r3 = (
        s * l2 * e2 * S12 * a2
        - (z1 + t2) * l1 * w1**2
        - s * l2 * e2 * C12 * w2**2
        + (e1 + t2) * g * S1
        + s * 2 * e2 * S12 * d2 * w2
        + (z1 + t2) * b1
        + s * e2 * C12 * b2
    )
    r4 = (
        -s * l1 * e2 * S12 * a1
        - s * l1 * e2 * C12 * w1**2
        - z2 * l2 * w2**2
        + s * e2 * g * S2
        - s * 2 * e2 * S12 * d1 * w1
        + s * e2 * C12 * b1
        + z2 * b2
    )
    return np.stack([r1, r2, r3, r4], -1)


def test_fig2b_differs_from_fig2a_exactly_by_eq4_sign_pattern(rel):
    a, b = fig2a(2), fig2b(2)
    q, qd, qdd = random_states(a, 50, 3)
    ta, tb = pb.inverse_dynamics(a, q, qd, qdd), pb.inverse_dynamics(b, q, qd, qdd)
    assert_forces_agree(ta, _eq4(a, q, qd, qdd, +1), a, q, qd, qdd)
    assert_forces_agree(tb, _eq4(b, q, qd, qdd, -1), b, q, qd, qdd)
    # the sign-flipped terms are exactly half the difference between the two models
    flipped = 0.5 * (_eq4(a, q, qd, qdd, +1) - _eq4(a, q, qd, qdd, -1))
    assert_forces_agree(ta - tb, 2 * flipped, a, q, qd, qdd, k=2 * K)  # two differences of forces
    assert np.abs(ta - tb).max() > 1.0


TREES = [(n, d, s) for d in (2, 3) for n, s in [(1, 10), (2, 11), (3, 12), (4, 13), (5, 14), (6, 15), (8, 16)]]


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_power_balance_on_random_trees(n, dim, seed):
    """d(T + Pi)/dt = tau . qd along a smooth motion, T and Pi summed over the point masses."""
    assert power_balance_residual(pb.inverse_dynamics, random_tree(n, dim, seed), seed) < POWER_BALANCE_TOL


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_mass_matrix_is_the_kinetic_energy_hessian(n, dim, seed, rel):
    """M from CRBA equals the Hessian of T(qd) summed over point masses, on consecutive calls."""
    m = random_tree(n, dim, seed)
    q, _, _ = random_states(m, 4, seed)
    M = pb.mass_matrix(m, q)
    I = np.eye(m.dof)
    scale = mass_matrix_scale(m, q)
    for s in range(q.shape[0]):
        T = lambda v: kinetic_energy(m, q[s : s + 1], v[None])[0]
        H = np.array([[T(I[i] + I[j]) - T(I[i]) - T(I[j]) for j in range(m.dof)] for i in range(m.dof)])
        # T is quadratic: the second difference is exact up to rounding; the three energies summed
        # are each at most the diagonal scales (|T(e_i + e_j)| <= 2 (M_ii + M_jj)), a few more ulps
        d = np.diagonal(scale[s])
        assert_close(M[s], H, scale[s] + d[:, None] + d[None, :], k=2 * K)


@pytest.mark.parametrize("n,dim,seed", TREES[::2])
def test_rnea_is_mass_matrix_times_acceleration_plus_bias(n, dim, seed, rel):
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 5, seed)
    tau = pb.inverse_dynamics(m, q, qd, qdd)
    assert_forces_agree(
        np.einsum("sij,sj->si", pb.mass_matrix(m, q), qdd) + pb.bias_forces(m, q, qd), tau, m, q, qd, qdd
    )
    assert np.array_equal(pb.inverse_dynamics_parallel(m, q, qd, qdd, threads=2), tau)  # the same RNEA per sample


@pytest.mark.parametrize("dim", [2, 3])
def test_frame_positions_are_the_point_masses(dim):
    m = random_tree(6, dim, 21)
    masses = list(m.masses)
    masses[2] = (masses[2][0], 0.0, masses[2][2])  # a zero middle mass: no body, point interpolated
    m = m.replace(masses=tuple(masses))
    q, _, _ = random_states(m, 5, 4)
    # positions are sums of at most n rod vectors of length <= 1.2: a few ulps of their total length
    total = q[:, -m.nlinks :].sum(axis=1)[:, None, None, None]
    assert_close(pb.point_mass_positions(m, q), point_mass_positions(m, q), total)


def test_generalised_forces_are_joint_moments_summed_back():
    """eq. (4): the generalised force of phi_1 is M1 - M2, where M2 is the physical moment at joint 2."""
    m = fig2a(2)
    q, qd, qdd = random_states(m, 5, 6)
    tj = pb.joint_torques(m, q, qd, qdd)
    names = pb.build_model(m).joint_names
    M1, M2 = tj[:, names.index("L1_phi")], tj[:, names.index("L2_phi")]
    tau = pb.inverse_dynamics(m, q, qd, qdd)
    assert np.array_equal(tau[:, 0], M1 - M2) and np.array_equal(tau[:, 1], M2)  # G^T: exactly these sums
