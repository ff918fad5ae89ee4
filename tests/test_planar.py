"""Closed forms of every matrix of eq. (5) against Lagrange's and Pinocchio's matrices, on trees."""

import numpy as np
import pytest
from conftest import assert_matrices_agree

from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.bench.studies.errata import LagrangeWitness, pinocchio_matrices
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import fig2a, fig2b, random_tree

TREES = [(1, 1), (2, 2), (3, 3), (4, 4), (5, 5), (6, 6), (6, 7)]


@pytest.mark.parametrize("n,seed", TREES)
def test_every_planar_matrix_equals_pinocchios(n, seed):
    m = random_tree(n, 2, seed)
    q, _, _ = random_states(m, 10, seed)
    assert_matrices_agree(numeric.planar_matrices(m, q), pinocchio_matrices(m, q), m, q)


@pytest.mark.parametrize("n,seed", TREES[:4])
def test_every_planar_matrix_equals_lagranges(n, seed):
    m = random_tree(n, 2, seed)
    q, _, _ = random_states(m, 10, seed)
    assert_matrices_agree(numeric.planar_matrices(m, q), LagrangeWitness().matrices(m, q), m, q)


def test_kinetic_symmetries_of_the_planar_matrices():
    """The mass matrix [[A_phi, Lambda_phi], [A_l, Lambda_l]] is symmetric; D_l = -H_phi^T (eq. 18's
    remark, already in 2D); D_phi_ij = l_i l_j H_l_ij."""
    m = random_tree(6, 2, 11)
    q, _, _ = random_states(m, 5, 1)
    M = numeric.planar_matrices(m, q)
    T = lambda x: np.swapaxes(x, -1, -2)
    _, _, l = q[:, :6], None, q[:, 6:]
    assert np.allclose(M["phi"]["A"], T(M["phi"]["A"]), atol=1e-14)
    assert np.allclose(M["l"]["Lambda"], T(M["l"]["Lambda"]), atol=1e-14)
    assert np.allclose(M["l"]["A"], T(M["phi"]["Lambda"]), atol=1e-14)
    assert np.allclose(M["l"]["D"], -T(M["phi"]["H"]), atol=1e-14)
    assert np.allclose(M["phi"]["D"], l[:, :, None] * l[:, None, :] * M["l"]["H"], atol=1e-14)


def test_two_link_entries_are_eq4_with_upper_and_lower_signs():
    """Eq. (4), read entry by entry: Fig. 2b has the signs of Fig. 2a flipped on every
    element that couples link 1 and link 2 and on the gravity of link 2."""
    q, _, _ = random_states(fig2a(2), 5, 2)
    a, b = numeric.planar_matrices(fig2a(2), q), numeric.planar_matrices(fig2b(2), q)
    for block in a:
        for name in a[block]:
            if name == "P":
                assert np.allclose(b[block][name], a[block][name] * [1, -1], atol=1e-14)
            else:
                assert np.allclose(b[block][name], a[block][name] * np.array([[1, -1], [-1, 1]]), atol=1e-14)
