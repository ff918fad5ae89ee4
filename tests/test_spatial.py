"""The corrected transitions (18): 3D matrices from the planar ones, against Pinocchio and Lagrange."""

import numpy as np
import pytest
import sympy as sp
from conftest import assert_matrices_agree

from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.matrix_method.closed_forms import planar, transitions as spatial
from exo_bench.bench.studies.errata import LagrangeWitness, pinocchio_matrices
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, fig5, random_tree

TREES = [(2, 1), (3, 2), (4, 3), (5, 4), (6, 5), (6, 6)]


@pytest.mark.parametrize("n,seed", TREES)
def test_every_transition_gives_pinocchios_3d_matrix(n, seed):
    m = random_tree(n, 3, seed)
    q, _, _ = random_states(m, 10, seed)
    assert_matrices_agree(numeric.matrices(m, q), pinocchio_matrices(m, q), m, q)


@pytest.mark.parametrize("mech", [fig5(3), exo5(3), random_tree(4, 3, 9)], ids=lambda m: m.name)
def test_every_transition_gives_lagranges_3d_matrix(mech):
    q, _, _ = random_states(mech, 8, 3)
    assert_matrices_agree(numeric.matrices(mech, q), LagrangeWitness().matrices(mech, q), mech, q)


def test_straightened_elements_are_the_quotients_by_cos_phi_ij():
    """x_ij = x_ij(straightened) cos(phi_i - phi_j) for a^phi, h^phi, lambda^l, d^l, which is what
    lets (18) be evaluated without dividing."""
    m = random_tree(5, 3, 8)
    q, _, _ = random_states(m, 6, 2)
    flat = numeric.planar_matrices(m, q)
    q0 = q.copy()
    q0[:, :5] = 0.0
    straight = numeric.planar_matrices(m, q0)
    phi = q[:, :5]
    C = np.cos(phi[:, :, None] - phi[:, None, :])
    for attr, (block, name) in spatial.QUOTIENTS.items():
        assert np.allclose(straight[block][name] * C, flat[block][name], rtol=0, atol=1e-14), attr


def test_transitions_are_finite_and_right_at_every_singular_configuration(rel):
    """cos(phi_i - phi_j) = 0, cos phi_i = 0, sin phi_i = 0 and l_j = 0 all at once."""
    m = random_tree(4, 3, 12)
    q, _, _ = random_states(m, 4, 5)
    q[:, :4] = [np.pi / 2, 0.0, np.pi, -np.pi / 2]  # phi_1 - phi_2 = pi/2, ...
    q[:, -1] = 0.0  # a rod retracted to zero length
    assert_matrices_agree(numeric.matrices(m, q), pinocchio_matrices(m, q), m, q)  # finite, and right


def _dot_product_oracle(dim):
    """Each element of eq. (5)/(17) from its definition, in sympy: ``c r_a,i . v_X,j`` with
    ``r_phi = l u_phi``, ``r_psi = l u_psi``, ``r_l = u`` of link i and, for link j, ``v_A = l u_phi``,
    ``v_B = l u_psi``, ``v_Lambda = u``, ``v_D = l u_phiphi``, ``v_E = l u_psipsi``, ``v_G = l u_phipsi``,
    ``v_H = u_phi``, ``v_K = u_psi`` (the coefficients of ``d2/dt2(l u)``, eq. 17's rate products);
    gravity ``nu r_a . up``. Differentiation by sympy, not the closed forms."""
    phi_i, phi_j, psi_i, psi_j, l_i, l_j, c, nu = sp.symbols("phi_i phi_j psi_i psi_j l_i l_j c nu", real=True)
    if dim == 2:
        u = lambda a, b: sp.Matrix([sp.cos(a), sp.sin(a)])
        up = sp.Matrix([0, 1])
    else:
        u = lambda a, b: sp.Matrix([sp.cos(b) * sp.cos(a), sp.cos(b) * sp.sin(a), sp.sin(b)])
        up = sp.Matrix([0, 0, 1])
    ui, uj = u(phi_i, psi_i), u(phi_j, psi_j)
    r = {"phi": l_i * ui.diff(phi_i), "psi": l_i * ui.diff(psi_i), "l": ui}
    v = {
        "A": l_j * uj.diff(phi_j),
        "B": l_j * uj.diff(psi_j),
        "Lambda": uj,
        "D": l_j * uj.diff(phi_j, 2),
        "E": l_j * uj.diff(psi_j, 2),
        "G": l_j * uj.diff(phi_j, psi_j),
        "H": uj.diff(phi_j),
        "K": uj.diff(psi_j),
    }
    blocks = ("phi", "l") if dim == 2 else ("phi", "psi", "l")
    names = ("A", "Lambda", "D", "H") if dim == 2 else tuple(v)
    pairs = {b: {x: c * r[b].dot(v[x]) for x in names} for b in blocks}
    gravity = {b: nu * r[b].dot(up) for b in blocks}
    return (phi_i, phi_j, psi_i, psi_j, l_i, l_j, c, nu), pairs, gravity


def _is_zero(expr) -> bool:
    return sp.simplify(sp.expand_trig(sp.expand(expr))) == 0


def test_planar_closed_forms_are_the_dot_products_of_their_definition():
    (phi_i, phi_j, _, _, l_i, l_j, c, nu), pairs, gravity = _dot_product_oracle(2)
    C, S = sp.cos(phi_i - phi_j), sp.sin(phi_i - phi_j)
    for block, fns in planar.PAIRS.items():
        for name, f in fns.items():
            assert _is_zero(f(c, l_i, l_j, C, S) - pairs[block][name]), (block, name)
        assert _is_zero(planar.GRAVITY[block](nu, l_i, sp.cos(phi_i), sp.sin(phi_i)) - gravity[block]), block


def test_corrected_transitions_are_the_dot_products_of_their_definition():
    """Every 3D element by the corrected (18), on sympy scalars (the symbolic backend of the same
    functions), equals its definition as a dot product of derivatives of the unit vectors."""
    (phi_i, phi_j, psi_i, psi_j, l_i, l_j, c, nu), pairs, gravity = _dot_product_oracle(3)
    C, S = sp.cos(phi_i - phi_j), sp.sin(phi_i - phi_j)

    def inputs(li, lj, a, b, pa, pb):
        now = {
            blk: {k: f(c, li, lj, sp.cos(a - b), sp.sin(a - b)) for k, f in fns.items()}
            for blk, fns in planar.PAIRS.items()
        }
        straight = {blk: {k: f(c, li, lj, 1, 0) for k, f in fns.items()} for blk, fns in planar.PAIRS.items()}
        return spatial.transition_inputs(now, straight, li, lj, sp.cos(pa), sp.sin(pa), sp.cos(pb), sp.sin(pb))

    t = inputs(l_i, l_j, phi_i, phi_j, psi_i, psi_j)
    t_swapped = inputs(l_j, l_i, phi_j, phi_i, psi_j, psi_i)  # element (j, i), for D_l = -(H_phi)^T
    for block, fns in spatial.PAIRS.items():
        for name, f in fns.items():
            value = spatial.d_l(spatial.h_phi(t_swapped)) if (block, name) == ("l", "D") else f(t)
            assert _is_zero(value - pairs[block][name]), (block, name)
    for block, f in spatial.GRAVITY.items():
        assert _is_zero(f(nu, l_i, sp.cos(psi_i), sp.sin(psi_i)) - gravity[block]), block


def test_a_link_that_carries_no_mass_has_finite_zero_gravity_terms():
    """A tip link without middle or end mass (and nothing below it): nu = 0, no term of its own,
    yet every 3D element and force is finite and Pinocchio's (no 0 / nu anywhere)."""
    from exo_bench import prepare
    from conftest import assert_forces_agree

    m = random_tree(3, 3, 21)
    m = m.replace(parent=(-1, 0, 1), masses=(m.masses[0], m.masses[1], (0.7, 0.0, 0.0)))
    q, qd, qdd = random_states(m, 6, 4)
    mats = numeric.matrices(m, q)
    assert all(np.isfinite(x).all() for b in mats.values() for x in b.values())
    assert np.all(mats["phi"]["P"] == 0)
    ref = prepare(m, "pinocchio").inverse_dynamics(q, qd, qdd)
    for method in ("matrix", "recurrence"):
        assert_forces_agree(prepare(m, method).inverse_dynamics(q, qd, qdd), ref, m, q, qd, qdd, what=method)
