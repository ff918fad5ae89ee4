"""The symbolic Lagrange II derivation against hand-derived equations (eqs. 2, 4, 6 and the
spatial one-link system from T and Pi), the matrix form's claim, and the structure cache."""

import numpy as np
import pytest
import sympy as sp

from exo_bench.lagrange import FormViolation, canonical_form, derive, extract_matrices, rebuild_equations
from exo_bench.lagrange.derivation import structure_of
from exo_bench.lagrange.matrix_form import MATRIX_NAMES
from exo_bench.models.mechanism.kinematics import kinetic_energy, potential_energy
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, fig1, fig2a, fig2b, random_tree


def _aggregates(S, i):
    """zeta_i, eta_i, theta_i of link i (0-based) in the shared symbols."""
    (m0, m1, m2), n = S.m[i], S.n[i]
    return m1 * n**2 + m2, m1 * n + m2, m0 + m1 + m2


def _same(a, b, S) -> bool:
    return canonical_form(sp.expand(a - b), S) == 0


def test_one_link_planar_is_eq2():
    d = derive(fig1(2), symbolic_parameters=True)
    S = d.symbols
    zeta, eta, _ = _aggregates(S, 0)
    phi, l, w, ld, wdd, ldd, g = S.phi[0], S.l[0], S.dphi[0], S.dl[0], S.ddphi[0], S.ddl[0], S.g
    M = l**2 * zeta * wdd + g * l * eta * sp.cos(phi) + 2 * l * zeta * ld * w
    F = -l * zeta * w**2 + g * eta * sp.sin(phi) + zeta * ldd
    assert _same(d.equations[0], M, S) and _same(d.equations[1], F, S)


def test_one_link_spatial_is_the_hand_derivation_from_T_and_Pi():
    """T = zeta/2 (l'^2 + l^2 (phi'^2 cos^2 psi + psi'^2)), Pi = g eta l sin psi (eqs. 11-12); the psi
    equation has 2 zeta l l' psi' where the printed eq. (14) has phi'."""
    d = derive(fig1(3), symbolic_parameters=True)
    S = d.symbols
    zeta, eta, _ = _aggregates(S, 0)
    psi, l, w, v, ld = S.psi[0], S.l[0], S.dphi[0], S.dpsi[0], S.dl[0]
    wdd, vdd, ldd, g = S.ddphi[0], S.ddpsi[0], S.ddl[0], S.g
    C, Sn = sp.cos(psi), sp.sin(psi)
    M_phi = zeta * l**2 * C**2 * wdd + 2 * zeta * l * C**2 * ld * w - 2 * zeta * l**2 * C * Sn * w * v
    M_psi = zeta * l**2 * vdd + zeta * l**2 * C * Sn * w**2 + 2 * zeta * l * ld * v + g * eta * l * C
    F = zeta * ldd - zeta * l * C**2 * w**2 - zeta * l * v**2 + g * eta * Sn
    for got, want in zip(d.equations, (M_phi, M_psi, F)):
        assert _same(got, want, S)
    printed_14 = M_psi - 2 * zeta * l * ld * v + 2 * zeta * l * ld * w
    assert not _same(d.equations[1], printed_14, S)


@pytest.mark.parametrize("make,sigma", [(fig2a, 1), (fig2b, -1)])
def test_two_links_are_eq4_with_upper_and_lower_signs(make, sigma):
    d = derive(make(2), symbolic_parameters=True)
    S = d.symbols
    z1, e1, _ = _aggregates(S, 0)
    z2, e2, t2 = _aggregates(S, 1)
    s, g = sigma, S.g
    (p1, p2), (l1, l2) = S.phi, S.l
    (w1, w2), (d1, d2), (a1, a2), (b1, b2) = S.dphi, S.dl, S.ddphi, S.ddl
    C1, S1, C2, S2 = sp.cos(p1), sp.sin(p1), sp.cos(p2), sp.sin(p2)
    C12, S12 = sp.cos(p1 - p2), sp.sin(p1 - p2)
    eq4 = [
        (z1 + t2) * l1**2 * a1
        + s * l1 * l2 * e2 * C12 * a2
        + s * l1 * l2 * e2 * S12 * w2**2
        + (e1 + t2) * g * l1 * C1
        + 2 * (z1 + t2) * l1 * d1 * w1
        + s * 2 * l1 * e2 * C12 * d2 * w2
        - s * l1 * e2 * S12 * b2,
        s * l1 * l2 * e2 * C12 * a1
        + z2 * l2**2 * a2
        - s * l1 * l2 * e2 * S12 * w1**2
        + s * e2 * g * l2 * C2
        + s * 2 * l2 * e2 * C12 * d1 * w1
        + 2 * z2 * l2 * d2 * w2
        + s * l2 * e2 * S12 * b1,
        s * l2 * e2 * S12 * a2
        - (z1 + t2) * l1 * w1**2
        - s * l2 * e2 * C12 * w2**2
        + (e1 + t2) * g * S1
        + s * 2 * e2 * S12 * d2 * w2
        + (z1 + t2) * b1
        + s * e2 * C12 * b2,
        -s * l1 * e2 * S12 * a1
        - s * l1 * e2 * C12 * w1**2
        - z2 * l2 * w2**2
        + s * e2 * g * S2
        - s * 2 * e2 * S12 * d1 * w1
        + s * e2 * C12 * b1
        + z2 * b2,
    ]
    for got, want in zip(d.equations, eq4):
        assert _same(got, want, S)


@pytest.mark.parametrize("n", [3, 4])
def test_planar_chain_A_phi_is_the_closed_form_eq6(n):
    """a_ij = (delta_ij zeta_i + (1 - delta_ij) eta_j + sum_{k>j} theta_k) l_i l_j cos(phi_i - phi_j), j >= i."""
    d = derive(chain(n, 2, seed=n), symbolic_parameters=True)
    S = d.symbols
    A = d.matrices["phi"]["A"]
    for i in range(n):
        for j in range(i, n):
            zeta_i, _, _ = _aggregates(S, i)
            _, eta_j, _ = _aggregates(S, j)
            below = sum(_aggregates(S, k)[2] for k in range(j + 1, n))
            a = ((zeta_i if i == j else eta_j) + below) * S.l[i] * S.l[j] * sp.cos(S.phi[i] - S.phi[j])
            assert _same(A[i, j], a, S) and _same(A[j, i], a, S)


TREES = [(n, dim, seed) for dim in (2, 3) for n, seed in [(1, 30), (2, 31), (3, 32), (3, 33)]]


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_matrices_rebuild_the_equations_exactly(n, dim, seed):
    m = random_tree(n, dim, seed)
    for symbolic in (True, False):
        d = derive(m, symbolic_parameters=symbolic)
        assert set(d.matrices) == ({"phi", "psi", "l"} if dim == 3 else {"phi", "l"})
        for blk, mats in d.matrices.items():
            assert tuple(mats) == MATRIX_NAMES[dim]
            assert mats["P"].shape == (n, 1) and all(mats[k].shape == (n, n) for k in mats if k != "P")
        rebuilt = rebuild_equations(d.matrices, d.symbols, d.g)
        assert all(sp.expand(a - b) == 0 for a, b in zip(rebuilt, d.equations))
        # and the public extraction from the plain expressions finds the same matrices
        again = extract_matrices(d.equations, d.symbols) if symbolic else None
        if again is not None:
            assert all(
                sp.expand(again[b][k] - d.matrices[b][k]) == sp.zeros(*d.matrices[b][k].shape)
                for b in again
                for k in again[b]
            )


@pytest.mark.parametrize(
    "extra,why",
    [
        ("l1*l2*cos(phi2)*dphi1*dphi2", "rates of two different links"),
        ("l1*dl1**2", "squared length rate"),
        ("l1*dphi1*ddphi1", "rate times acceleration"),
        ("dphi1*dl2", "angle rate of one link times length rate of another"),
        ("l1*sin(phi1)", "rate-free term without g"),
        ("g*dphi1*l1", "g times a rate"),
    ],
)
def test_form_check_rejects_terms_outside_the_matrix_form(extra, why):
    m = random_tree(2, 3, 34)
    d = derive(m, symbolic_parameters=True)
    extract_matrices(d.equations, d.symbols)  # the true equations fit the form
    bad = list(d.equations)
    S = d.symbols
    names = {x.name: x for x in S.q + S.qd + S.qdd + (S.g,)}
    bad[1] = bad[1] + sp.sympify(extra, locals=names)
    with pytest.raises(FormViolation, match="equation phi2"):
        extract_matrices(bad, d.symbols)


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_mass_matrix_is_symmetric(n, dim, seed):
    d = derive(random_tree(n, dim, seed), symbolic_parameters=True)
    M = d.mass_matrix
    assert sp.expand(M - M.T) == sp.zeros(M.rows, M.cols)


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_energies_are_those_of_the_point_mass_kinematics(n, dim, seed):
    """T and Pi of the derivation against models.kinematics (positions placed by another code)."""
    m = random_tree(n, dim, seed)
    d = derive(m)
    S = d.symbols
    q, qd, _ = random_states(m, 20, seed)
    T = sp.lambdify(S.q + S.qd, d.kinetic_energy, "numpy")(*q.T, *qd.T)
    Pi = sp.lambdify(S.q, d.potential_energy, "numpy")(*q.T)
    assert np.allclose(T, kinetic_energy(m, q, qd), rtol=1e-13, atol=1e-12)
    assert np.allclose(Pi, potential_energy(m, q), rtol=1e-13, atol=1e-12)


def test_trees_of_one_structure_share_one_symbolic_derivation():
    a = random_tree(3, 3, 40)
    b = a.replace(masses=tuple((x * 2, y, z + 1) for x, y, z in a.masses), n=(0.3, 0.4, 0.5), g=1.62)
    sa, sb = derive(a, symbolic_parameters=True), derive(b, symbolic_parameters=True)
    assert sa is sb
    na, nb = derive(a), derive(b)
    assert na is derive(a) and na is not nb
    # numbers are substituted exactly: no floats, no parameter symbols left
    params = {x for ms in na.symbols.m for x in ms} | set(na.symbols.n) | {na.symbols.g}
    for e in na.equations:
        assert not e.atoms(sp.Float) and not (e.free_symbols & params)
    vals = {**{x: sp.Rational(v) for x, v in na.symbols.parameter_values(b).items()}}
    assert all(sp.expand(e.xreplace(vals) - f) == 0 for e, f in zip(sb.equations, nb.equations))


def test_zero_masses_are_structural_zeros():
    m = random_tree(3, 2, 41)
    masses = list(m.masses)
    masses[1] = (masses[1][0], 0.0, masses[1][2])
    z = m.replace(masses=tuple(masses))
    assert structure_of(z) != structure_of(m)
    d = derive(z, symbolic_parameters=True)
    assert all(not e.has(d.symbols.m[1][1]) for e in d.equations)
    assert any(e.has(d.symbols.m[1][1]) for e in derive(m, symbolic_parameters=True).equations)


@pytest.mark.parametrize("m", [fig2b(2), random_tree(2, 3, 42)], ids=lambda m: m.name)
def test_textbook_engine_derives_the_same_equations(m):
    """engine='expr' (sympy.diff and expand on expressions) against the polynomial-ring engine."""
    a = derive(m, symbolic_parameters=True)
    b = derive(m, symbolic_parameters=True, engine="expr")
    assert all(sp.expand(x - y) == 0 for x, y in zip(a.equations, b.equations))


def test_canonical_form_tells_equal_from_unequal():
    S = derive(fig2a(2), symbolic_parameters=True).symbols
    p1, p2 = S.phi
    assert canonical_form(sp.cos(p1 - p2) - sp.cos(p1) * sp.cos(p2) - sp.sin(p1) * sp.sin(p2), S) == 0
    assert canonical_form(sp.cos(p1) ** 2 + sp.sin(p1) ** 2 - 1, S) == 0
    assert canonical_form(sp.cos(p1) ** 2 - sp.sin(p1) ** 2 - 1, S) != 0


def test_bad_engine_and_bad_equation_count_are_value_errors():
    with pytest.raises(ValueError, match="engine"):
        derive(fig1(2), engine="mathematica")
    S = derive(fig1(2), symbolic_parameters=True).symbols
    with pytest.raises(ValueError, match="expected 2 equations"):
        extract_matrices([S.g], S)
