"""Forward dynamics (models/simulation/forward_dynamics.py): the mass matrix and bias forces from inverse
dynamics, the exact singular configurations, the configuration-independent equilibrated
condition number, and the integrator plumbing (budgets, states outside the domain)."""

import math

import numpy as np

from exo_bench import prepare
from exo_bench.models.runtime.prepared import terms_from_inverse_dynamics
import pytest
from conftest import assert_close, assert_forces_agree, mass_matrix_scale

from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.simulation.forward_dynamics import make_rhs, simulate
from exo_bench.models.mechanism.singularity import SingularConfigurationError, singular_reasons
from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.mechanism.kinematics import kinetic_energy, point_mass_velocities
from exo_bench.models.states.states import split
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, fig1, random_tree

TREES = [random_tree(5, 3, 11), random_tree(5, 2, 12), random_tree(4, 3, 13)]
EPS = np.finfo(float).eps


@pytest.mark.parametrize("mech", TREES, ids=lambda m: m.name)
def test_inverse_dynamics_is_linear_in_qdd_so_it_gives_M_and_h(mech, rel):
    """h = ID(q, qd, 0) and M e_k = ID(q, 0, e_k) - ID(q, 0, 0) from RNEA equal CRBA and
    nonLinearEffects, two different algorithms."""
    q, qd, _ = random_states(mech, 5, 1)
    rnea = lambda a, b, c: pb.inverse_dynamics(mech, a, b, c)  # noqa: E731 - RNEA only, no CRBA
    M, h = terms_from_inverse_dynamics(rnea, mech.dof, q, qd)
    scale = mass_matrix_scale(mech, q, derived=True)  # the error model of tests/conftest.py
    assert_close(M, pb.mass_matrix(mech, q), scale)
    assert_forces_agree(h, pb.bias_forces(mech, q, qd), mech, q, qd, None)
    assert_close(M, np.swapaxes(M, 1, 2), scale + np.swapaxes(scale, 1, 2))


def test_terms_from_inverse_dynamics_make_one_call():
    mech = TREES[0]
    q, qd, _ = random_states(mech, 3, 2)
    calls = []

    def counting(a, b, c):
        calls.append(a.shape)
        return pb.inverse_dynamics(mech, a, b, c)

    terms_from_inverse_dynamics(counting, mech.dof, q, qd)
    assert calls == [(3 * (mech.dof + 2), mech.dof)]


@pytest.mark.parametrize("mech", TREES, ids=lambda m: m.name)
def test_mass_coupling_gives_the_kinetic_energy_of_the_point_masses(mech, rel):
    """T = 1/2 sum_ij mu_ij w_i' . w_j' with w_i = s_i l_i u_i the rod vectors, against the point masses."""
    q, qd, _ = random_states(mech, 6, 3)
    mu = coupling(mech)
    # w_i': the velocity of the end of link i relative to its start (the end of its parent, or O)
    v = point_mass_velocities(mech, q, qd)  # (S, n, 3, dim)
    parent_end = np.zeros_like(v[:, :, 0])
    for i, p in enumerate(mech.parent):
        if p >= 0:
            parent_end[:, i] = v[:, p, 2]
    wd = v[:, :, 2] - parent_end  # (S, n, dim)
    T = 0.5 * np.einsum("ij,sik,sjk->s", mu, wd, wd)
    assert rel(T, kinetic_energy(mech, q, qd)) < 1e-13


@pytest.mark.parametrize("mech", TREES + [exo5(3)], ids=lambda m: m.name)
def test_forward_dynamics_inverts_inverse_dynamics(mech, rel):
    q, qd, qdd = random_states(mech, 8, 4)
    tau = pb.inverse_dynamics(mech, q, qd, qdd)
    # Error model: tau, M and h carry errors of a few ulps of their largest entries, and the solve
    # amplifies them by at most cond(M): k * eps * cond(M) with k = 10 (0.2 to 0.7 measured).
    cond = fd.condition_numbers(pb.mass_matrix(mech, q))[0].max()
    assert rel(fd.accelerations(prepare(mech, "pinocchio"), q, qd, tau), qdd) < 10 * EPS * cond


@pytest.mark.parametrize("mech", TREES + [exo5(3), exo5(2)], ids=lambda m: m.name)
def test_equilibrated_condition_number_is_that_of_the_mass_distribution_at_every_configuration(mech):
    """D^-1/2 M D^-1/2 is orthogonally similar to mu_s (x) I: its condition number does not depend on q,
    while cond(M) itself does (it carries the scaling l_i cos psi_i, l_i, 1)."""
    q, _, _ = random_states(mech, 6, 5)
    raw, eq = fd.condition_numbers(pb.mass_matrix(mech, q))
    mu = coupling(mech)
    r = 1 / np.sqrt(np.diag(mu))
    expected = np.linalg.cond(mu * r[:, None] * r[None, :])
    # M is computed to a few ulps of its largest entry; equilibrating by its diagonal magnifies that on
    # the smallest entries by at most the spread of the diagonal, itself at most cond(M): the bound is
    # k * eps * cond(M) with k = 10 (measured: below 0.05 of it).
    assert np.abs(eq / expected - 1).max() < 10 * EPS * raw.max()
    assert raw.max() / raw.min() > 1.05  # cond(M) does move with the configuration


def test_vertical_rod_is_singular_for_forward_dynamics_but_not_for_inverse_dynamics():
    mech = exo5(3)
    n = mech.nlinks
    q, qd, qdd = random_states(mech, 1, 6)
    q[0, n + 2] = math.pi / 2  # psi_3: the swing thigh stands vertical
    tau = pb.inverse_dynamics(mech, q, qd, qdd)
    assert np.isfinite(tau).all()
    M = pb.mass_matrix(mech, q)[0]
    # the azimuth column of link 3 vanishes: l_3 cos psi_3 (-sin phi_3, cos phi_3, 0) with cos psi_3 = 6e-17
    assert np.abs(M[:, 2]).max() < 1e-14 * np.abs(M).max()
    reasons = singular_reasons(mech, q)[0]
    assert len(reasons) == 1 and "link 3" in reasons[0] and "vertical" in reasons[0]
    with pytest.raises(SingularConfigurationError, match="link 3 .*vertical rod"):
        fd.accelerations(prepare(mech, "pinocchio"), q, qd, tau)


def test_near_vertical_rod_is_regular_and_its_condition_number_grows_like_1_over_cos_squared():
    mech = fig1(3)
    q, _, _ = random_states(mech, 1, 7)
    conds = []
    for d in (1e-2, 1e-3, 1e-4):
        q[0, 1] = math.pi / 2 - d
        assert singular_reasons(mech, q) == [[]]
        conds.append(fd.condition_numbers(pb.mass_matrix(mech, q))[0][0])
    # one link: M = diag(zeta l^2 cos^2 psi, zeta l^2, zeta), so cond grows by 100 per decade of d
    assert conds[1] / conds[0] == pytest.approx(100, rel=0.02)
    assert conds[2] / conds[1] == pytest.approx(100, rel=0.02)


def test_zero_length_rod_and_massless_link_are_singular():
    mech = exo5(3)
    q, qd, qdd = random_states(mech, 2, 8)
    q[1, 2 * mech.nlinks + 1] = 0.0  # l_2 = 0 in sample 1
    reasons = singular_reasons(mech, q)
    assert reasons[0] == [] and "l2 = 0" in reasons[1][0]
    masses = list(mech.masses)
    masses[3] = (masses[3][0], 0.0, 0.0)  # swing shin: only the mass at its hinge
    massless = mech.replace(masses=tuple(masses))
    r = singular_reasons(massless, q[:1])[0]
    assert len(r) == 1 and "link 4" in r[0] and "no mass" in r[0]
    assert np.isinf(fd.condition_numbers(pb.mass_matrix(massless, q[:1]))[1][0])


def test_a_chain_whose_last_mass_sits_mid_rod_only_is_singular():
    """mu_ii > 0 for every link, yet mu is singular: the last rod's middle mass moves with
    w_parent + n w_last, so w_last' = -w_parent'/n moves nothing (caught by mu's eigenvalues)."""
    base = random_tree(2, 2, 3).replace(parent=(-1, 0), sign=(1, 1))
    m = base.replace(masses=((1.0, 0.0, 0.0), (0.0, 2.0, 0.0)))
    q, _, _ = random_states(m, 1, 9)
    r = singular_reasons(m, q)[0]
    assert len(r) == 1 and "mass distribution" in r[0]


def test_budget_and_states_outside_the_domain_are_recorded_not_raised():
    mech = fig1(2)
    q0 = np.array([[-1.0, 0.5]])
    ctrl = fd.rod_spring_damper(mech, 1e3, 0.0, 0.5)
    model = prepare(mech, "pinocchio")
    sim = simulate(model, q0, np.zeros_like(q0), (0.0, 10.0), ctrl, integrator="RK45", rtol=1e-10, max_evaluations=200)
    assert sim.status.startswith("budget exceeded") and not sim.ok and sim.nfev == 201
    rhs, count = make_rhs(model, ctrl)
    y = np.array([[-1.0, -1.0], [0.5, -0.1], [0.0, 0.0], [0.0, 0.0]])  # columns: l = 0.5 and l = -0.1
    f = rhs(0.0, y)
    assert np.isfinite(f[:, 0]).all() and np.isnan(f[2:, 1]).all() and count["rejected"] == 1


def test_simulate_refuses_a_singular_initial_state():
    mech = fig1(3)
    q0 = np.array([[0.3, math.pi / 2, 0.4]])
    with pytest.raises(SingularConfigurationError, match="vertical"):
        simulate(prepare(mech, "matrix"), q0, np.zeros_like(q0), (0.0, 1.0), fd.rod_spring_damper(mech, 1e3, 0.0, 0.4))


def test_spring_damper_forces_act_on_the_rods_only():
    mech = exo5(2)
    q, qd, _ = random_states(mech, 3, 10)
    tau = fd.rod_spring_damper(mech, 2e3, 5.0, 0.4)(0.0, q, qd)
    _, l = split(mech, q)[0], split(mech, q)[2]
    _, ld = split(mech, qd)[0], split(mech, qd)[2]
    assert np.all(tau[:, : mech.nlinks] == 0)
    assert np.allclose(tau[:, mech.nlinks :], -2e3 * (l - 0.4) - 5.0 * ld)
    # the spring energy is the potential of those forces: dV/dl = -F (damping aside)
    h = 1e-6
    dq = np.zeros_like(q)
    dq[:, -1] = h
    dV = (fd.spring_energy(mech, q + dq, 2e3, 0.4) - fd.spring_energy(mech, q - dq, 2e3, 0.4)) / (2 * h)
    assert np.allclose(dV, 2e3 * (l[:, -1] - 0.4), rtol=1e-7)
