"""The corrected transitions (18): 3D matrices from the planar ones, against Pinocchio and Lagrange."""

import numpy as np
import pytest

from exo_bench.matrix_method import numeric, planar, spatial
from exo_bench.matrix_method.coefficients import signed_coupling
from exo_bench.bench.errata import LagrangeWitness, pinocchio_matrices
from exo_bench.models.motion import random_states
from exo_bench.models.presets import exo5, fig5, random_tree

TREES = [(2, 1), (3, 2), (4, 3), (5, 4), (6, 5), (6, 6)]


@pytest.mark.parametrize("n,seed", TREES)
def test_every_transition_gives_pinocchios_3d_matrix(n, seed, rel):
    m = random_tree(n, 3, seed)
    q, _, _ = random_states(m, 10, seed)
    ours, ref = numeric.matrices(m, q), pinocchio_matrices(m, q)
    scale = max(np.abs(x).max() for b in ref.values() for x in b.values())
    for block in ref:
        for name in ref[block]:
            assert np.abs(ours[block][name] - ref[block][name]).max() < 1e-12 * scale, (block, name)


@pytest.mark.parametrize("mech", [fig5(3), exo5(3), random_tree(4, 3, 9)], ids=lambda m: m.name)
def test_every_transition_gives_lagranges_3d_matrix(mech):
    q, _, _ = random_states(mech, 8, 3)
    ours, ref = numeric.matrices(mech, q), LagrangeWitness().matrices(mech, q)
    for block in ref:
        for name in ref[block]:
            assert np.abs(ours[block][name] - ref[block][name]).max() < 1e-12 * max(1.0, np.abs(ref[block][name]).max())


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
    q[:, :4] = [np.pi / 2, 0.0, np.pi, -np.pi / 2]        # phi_1 - phi_2 = pi/2, ...
    q[:, -1] = 0.0                                        # a rod retracted to zero length
    ours = numeric.matrices(m, q)
    ref = pinocchio_matrices(m, q)
    for block in ref:
        for name in ref[block]:
            assert np.isfinite(ours[block][name]).all()
            assert np.abs(ours[block][name] - ref[block][name]).max() < 1e-12 * max(1.0, np.abs(ref[block][name]).max())


def test_transitions_work_on_sympy_scalars_as_on_arrays():
    """The same functions serve the numeric and symbolic paths: one entry evaluated with floats
    equals the array evaluation."""
    m = random_tree(3, 3, 4)
    q, _, _ = random_states(m, 1, 6)
    arr = numeric.matrices(m, q)
    c = signed_coupling(m)
    phi, psi, l = q[0, :3], q[0, 3:6], q[0, 6:]
    i, j = 2, 0 if c[2, 0] else 2
    C, S = np.cos(phi[i] - phi[j]), np.sin(phi[i] - phi[j])
    now = {b: {k: f(c[i, j], l[i], l[j], C, S) for k, f in fns.items()} for b, fns in planar.PAIRS.items()}
    straight = {b: {k: f(c[i, j], l[i], l[j], 1.0, 0.0) for k, f in fns.items()} for b, fns in planar.PAIRS.items()}
    t = spatial.transition_inputs(now, straight, l[i], l[j], np.cos(psi[i]), np.sin(psi[i]), np.cos(psi[j]), np.sin(psi[j]))
    for block, fns in spatial.PAIRS.items():
        for name, f in fns.items():
            if (block, name) != ("l", "D"):
                assert f(t) == pytest.approx(arr[block][name][0, i, j], rel=1e-13, abs=1e-14)
