"""The mass coefficients mu, nu of the closed forms against the point masses' energies and eq. (6)."""

import numpy as np
import pytest
import sympy as sp
from conftest import mass_coupling_oracle

from exo_bench.matrix_method.closed_forms import coefficients as co
from exo_bench.matrix_method import symbolic as sco
from exo_bench.models.mechanism import aggregates as ag
from exo_bench.models.mechanism.kinematics import kinetic_energy, potential_energy, unit_vectors
from exo_bench.models.states.states import split
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, fig5, random_tree
from exo_bench.models.mechanism.symbols import symbols_for


@pytest.mark.parametrize("n,dim,seed", [(1, 2, 1), (4, 2, 2), (6, 3, 3), (7, 3, 4), (5, 2, 5)])
def test_kinetic_and_potential_energy_are_quadratic_forms_in_the_rod_vectors(n, dim, seed, rel):
    """T = 1/2 sum_ij mu_ij w_i' . w_j' and Pi = g sum nu_i w_i . up, w_i = s_i l_i u_i (the
    energies summed over the point masses by models.kinematics)."""
    m = random_tree(n, dim, seed)
    q, qd, _ = random_states(m, 20, seed)
    _, _, l = split(m, q)
    u, u_phi, u_psi = unit_vectors(m, q)
    phid, psid, ld = split(m, qd)
    udot = u_phi * phid[..., None] + (0 if u_psi is None else u_psi * psid[..., None])
    s = m.sign_array[None, :, None]
    w = s * l[..., None] * u
    wd = s * (ld[..., None] * u + l[..., None] * udot)
    T = 0.5 * np.einsum("ij,sik,sjk->s", ag.coupling(m), wd, wd)
    Pi = m.g * np.einsum("i,si->s", co.signed_gravity(m) * m.sign_array, w[..., -1])
    assert rel(T, kinetic_energy(m, q, qd)) < 1e-13
    assert rel(Pi, potential_energy(m, q)) < 1e-13


def test_chain_coupling_is_the_bracket_of_eq6():
    """For a chain, mu_ij (j >= i) = delta_ij zeta_i + (1 - delta_ij) eta_j + sum_{k>j} theta_k."""
    m = chain(5, 2, seed=3)
    zeta, eta, theta = ag.link_aggregates(m)
    mu = ag.coupling(m)
    for i in range(5):
        for j in range(i, 5):
            expected = (zeta[i] if i == j else eta[j]) + theta[j + 1 :].sum()
            assert mu[i, j] == pytest.approx(expected, rel=1e-15) and mu[j, i] == mu[i, j]


def test_links_on_different_branches_do_not_couple():
    m = random_tree(8, 3, 7)
    mu = ag.coupling(m)
    related = m.ancestor_or_self | m.ancestor_or_self.T
    assert np.all(mu[~related] == 0) and np.all(mu[related] > 0)


def test_reversed_links_flip_the_sign_of_couplings_across_the_branch_point():
    """Fig. 5: links 3, 4 reversed, so c_13, c_14, c_23, c_24 change sign (eq. 20), c_34 does not."""
    m = fig5(2)
    c, mu = co.signed_coupling(m), ag.coupling(m)
    assert np.array_equal(np.sign(c), np.outer([1, 1, -1, -1], [1, 1, -1, -1]))
    assert np.array_equal(np.abs(c), mu)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_recurrence_increments_add_up_to_the_direct_coefficients(seed):
    m = random_tree(9, 3, seed)
    c, nu = np.zeros((9, 9)), np.zeros(9)
    for k in range(9):
        idx, dc, dnu = co.recurrence_increments(m, k)
        c[np.ix_(idx, idx)] += dc
        nu[idx] += dnu
    mu_ref, nu_ref = mass_coupling_oracle(m)  # from the point masses, not from eq. (6)
    s = m.sign_array
    # a few roundings of sums of at most 3n masses: 4 n eps relative
    tol = 4 * m.nlinks * np.finfo(float).eps
    assert np.allclose(c, mu_ref * np.outer(s, s), rtol=tol, atol=0)
    assert np.allclose(nu, nu_ref * s, rtol=tol, atol=0)


def _tree_with_zero_masses(seed):
    m = random_tree(7, 3, seed)
    rng = np.random.default_rng(seed)
    masses = [tuple(0.0 if rng.random() < 0.3 else x for x in ms) for ms in m.masses]
    if not any(x for ms in masses for x in ms):
        masses[0] = (0.0, 0.0, 1.0)
    return m.replace(masses=tuple(masses))


@pytest.mark.parametrize("seed", [11, 12, 13, 14])
def test_coefficients_are_those_of_the_point_masses(seed):
    """mu, nu (models.aggregates), the signed c and nu s (matrix_method.coefficients), the descendant
    masses, the per-link aggregates and the symbolic twins, all against the sums over the point
    masses of tests/conftest.py (mass m at fraction f of link k rides on its ancestors' rods with
    weight 1 and on k's with weight f), on trees with zero masses."""
    m = _tree_with_zero_masses(seed)
    mu_ref, nu_ref = mass_coupling_oracle(m)
    s = m.sign_array
    tol = 4 * m.nlinks * np.finfo(float).eps
    close = lambda a, b: np.allclose(a, b, rtol=tol, atol=tol * max(1.0, np.abs(b).max()))
    assert close(ag.coupling(m), mu_ref) and close(ag.gravity_coupling(m), nu_ref)
    assert close(co.signed_coupling(m), mu_ref * np.outer(s, s)) and close(co.signed_gravity(m), nu_ref * s)
    masses, f = m.mass_array, m.n_array if hasattr(m, "n_array") else np.array(m.n)
    zeta, eta, theta = ag.link_aggregates(m)
    assert close(zeta, masses[:, 1] * f**2 + masses[:, 2]) and close(eta, masses[:, 1] * f + masses[:, 2])
    assert close(theta, masses.sum(axis=1))
    below = np.array([sum(masses[j].sum() for j in range(m.nlinks) if i in m.ancestors[j]) for i in range(m.nlinks)])
    assert close(ag.descendant_mass(m), below)
    assert close(np.array(ag.descendant_sums(m, list(theta))), below)  # the default zero of any arithmetic
    mu_default, nu_default = ag.coupling_entries(m, zeta, eta, theta)
    assert close(np.array(mu_default, dtype=float), mu_ref) and close(np.array(nu_default, dtype=float), nu_ref)
    S = symbols_for(m.nlinks, 3)
    c, nu = sco.symbolic_coupling(m, S, symbolic_parameters=False)  # exact Rationals of the floats
    assert close(np.array([[float(x) for x in row] for row in c]), mu_ref * np.outer(s, s))
    assert close(np.array([float(x) for x in nu]), nu_ref * s)
    gc, gnu = co.generic_coupling(m, sco.parameters(m, S, False))  # the default zero of any arithmetic
    assert close(np.array(gc, dtype=float), mu_ref * np.outer(s, s)) and close(np.array(gnu, dtype=float), nu_ref * s)
    for k in range(m.nlinks):  # eq. (25)'s increments, both twins
        idx, dc, dnu = co.recurrence_increments(m, k)
        gidx, gdc, gdnu = co.generic_recurrence_increments(m, sco.parameters(m, S, False), k)
        assert list(idx) == list(gidx) == sorted(m.ancestors[k]) + [k]
        assert close(np.array(gdc, dtype=float), dc) and close(np.array(gdnu, dtype=float), dnu)


def test_symbolic_coupling_equals_the_numeric_one():
    m = random_tree(5, 3, 4)
    S = symbols_for(5, 3)
    c, nu = sco.symbolic_coupling(m, S, symbolic_parameters=True)
    values = S.parameter_values(m)
    num_c = np.array([[float(sp.sympify(x).subs(values)) for x in row] for row in c])
    num_nu = np.array([float(sp.sympify(x).subs(values)) for x in nu])
    assert np.allclose(num_c, co.signed_coupling(m), rtol=1e-14, atol=0)
    assert np.allclose(num_nu, co.signed_gravity(m), rtol=1e-14, atol=0)
    exact, _ = sco.symbolic_coupling(m, S, symbolic_parameters=False)
    assert all(isinstance(x, sp.Rational) for row in exact for x in row)


def test_the_cached_coefficients_are_read_only():
    """mu, nu, c and nu s are cached per mechanism and shared by every model of it: writing into
    one would change every later result, so each is a read-only array."""
    m = random_tree(3, 2, 5)
    for arr in (ag.coupling(m), ag.gravity_coupling(m), co.signed_coupling(m), co.signed_gravity(m)):
        with pytest.raises(ValueError, match="read-only"):
            arr[0, ...] = 1.0
