"""Net joint loads from the point masses, checked against Pinocchio's RNEA and finite differences.

Pinocchio computes its joint torques on the generated URDF (its own kinematics and recursion);
the net joint loads here are Newton-Euler sums over point masses placed by eq. (7). Agreement is
asserted at ``k * eps * scale`` with the scale the largest |joint torque| of the batch: both sides
are sums of a few dozen products of that size.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.models.mechanism.kinematics import net_joint_loads, point_mass_accelerations, sagittal_moments, subtree
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.gait.motion import random_states, smooth_random_motion
from exo_bench.models.engines.pinocchio_backend import build_model, joint_torques
from exo_bench.models.mechanism.presets import exo5, random_tree

EPS = np.finfo(float).eps
K = 64


def _rows(mech, kind):
    names = build_model(mech).joint_names
    return [names.index(f"L{k + 1}_{kind}") for k in range(mech.nlinks)]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("dim", [2, 3])
def test_accelerations_are_the_time_derivative_of_the_velocities(seed, dim):
    mech = random_tree(5, dim, seed)
    f = lambda t: smooth_random_motion(mech, t, seed=seed)
    t, h = np.linspace(0.1, 1.9, 9), 1e-4
    m = [f(t + k * h) for k in (-2, -1, 1, 2)]
    v = [point_mass_velocities(mech, x.q, x.qd) for x in m]
    fd = (v[0] - 8 * v[1] + 8 * v[2] - v[3]) / (12 * h)  # fourth order: error ~ h^4 |v'''''|
    mo = f(t)
    a = point_mass_accelerations(mech, mo.q, mo.qd, mo.qdd)
    assert np.abs(a - fd).max() <= 1e-7 * max(1.0, np.abs(a).max())


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("dim", [2, 3])
def test_azimuth_joint_torques_are_the_vertical_net_joint_moments(seed, dim):
    """A relative azimuth turns the whole subtree about the vertical through its joint."""
    mech = random_tree(6, dim, seed)
    q, qd, qdd = random_states(mech, 12, seed)
    M, _ = net_joint_loads(mech, q, qd, qdd)
    tj = joint_torques(mech, q, qd, qdd)
    mz = M[..., 2] if dim == 3 else M
    assert np.abs(tj[:, _rows(mech, "phi")] - mz).max() <= K * EPS * np.abs(tj).max()


@pytest.mark.parametrize("seed", range(5))
def test_elevation_joint_torques_are_the_moment_at_the_joint_minus_the_childrens(seed):
    """psi_k is absolute: its generalised force is the moment about the elevation axis at the
    start of link k minus that at its children's joints (the same axis), so it equals the net joint
    moment only for a leaf link."""
    mech = random_tree(6, 3, seed)
    q, qd, qdd = random_states(mech, 12, seed)
    M, _ = net_joint_loads(mech, q, qd, qdd)
    tj = joint_torques(mech, q, qd, qdd)
    phi = q[:, : mech.nlinks]
    for k, row in enumerate(_rows(mech, "psi")):
        axis = np.stack([np.sin(phi[:, k]), -np.cos(phi[:, k]), np.zeros(len(q))], axis=-1)  # -e_y turned by phi_k
        on_axis = lambda j: np.einsum("sd,sd->s", M[:, j], axis)
        expected = on_axis(k) - sum((on_axis(c) for c in mech.children[k]), np.zeros(len(q)))
        assert np.abs(tj[:, row] - expected).max() <= K * EPS * np.abs(tj).max(), f"link {k + 1}"


def test_the_net_moment_at_the_support_point_balances_gravity_for_a_mechanism_at_rest():
    """At rest the net moment at O is the moment of the weights: g x (sum m (p - O)) with g down."""
    mech = exo5(3)
    q, _, _ = random_states(mech, 6, 3)
    zero = np.zeros_like(q)
    M, F = net_joint_loads(mech, q, zero, zero)
    P = point_mass_positions(mech, q)
    m = mech.mass_array
    com = np.einsum("ib,sibd->sd", m, P)  # sum m p (about O = 0)
    expected = np.cross(com, np.array([0.0, 0.0, mech.g]))  # sum p x m (a - g), a = 0
    np.testing.assert_allclose(M[:, 0], expected, rtol=0, atol=K * EPS * np.abs(expected).max())
    np.testing.assert_allclose(F[:, 0], np.tile([0.0, 0.0, mech.g * mech.total_mass], (6, 1)), rtol=1e-14)


def test_sagittal_moment_is_positive_when_it_turns_a_rod_from_forward_to_up():
    """A horizontal rod pointing along +x, held at rest: its weight turns it down (clockwise in x-z
    seen with x right and z up), so the joint must push it counter-clockwise: a positive moment."""
    mech = exo5(3)
    q = np.zeros((1, mech.dof))
    q[0, -5:] = 0.4  # lengths; every angle 0: all rods along +x, horizontal
    M, _ = net_joint_loads(mech, q, np.zeros_like(q), np.zeros_like(q))
    trunk = 4  # a leaf with sign +1: it points along +x
    expected = mech.g * 0.4 * (mech.n[trunk] * mech.masses[trunk][1] + mech.masses[trunk][2])
    assert sagittal_moments(mech, M)[0, trunk] == pytest.approx(expected, rel=1e-14)


def test_subtree_of_the_exoskeleton():
    mech = exo5(3)
    assert subtree(mech, 0) == (0, 1, 2, 3, 4) and subtree(mech, 1) == (1, 2, 3, 4) and subtree(mech, 2) == (2, 3)
