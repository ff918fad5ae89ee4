"""The recurrence (22)-(26) for trees: against Lagrange, Pinocchio and the direct closed forms."""

import numpy as np
import pytest

from exo_bench.lagrange import numeric as lagrange_numeric
from exo_bench.matrix_method import numeric, recurrence, symbolic
from exo_bench.bench.errata import prefix, prefix_states
from exo_bench.models import pinocchio_backend as pb
from exo_bench.models.motion import random_states
from exo_bench.models.presets import exo5, random_tree

TREES = [(1 + s % 6, 2 if (s // 6) % 2 == 0 else 3, s) for s in range(100)]


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_recurrence_agrees_with_pinocchio_and_lagrange_on_random_trees(n, dim, seed, rel):
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 8, seed)
    tau = recurrence.inverse_dynamics(m, q, qd, qdd)
    assert rel(tau, pb.inverse_dynamics(m, q, qd, qdd)) < 1e-10
    if n <= 3:
        assert rel(tau, lagrange_numeric.inverse_dynamics(m, q, qd, qdd)) < 1e-10


@pytest.mark.parametrize("dim,seed", [(2, 1), (3, 2), (3, 3)])
def test_recurrence_equals_the_direct_closed_forms_for_every_n_up_to_20(dim, seed):
    m = random_tree(20, dim, seed)
    q, _, _ = random_states(m, 4, seed)
    for n, mats in recurrence.matrix_sequence(m, q):
        direct = numeric.matrices(prefix(m, n), prefix_states(m, q, n))
        for block in direct:
            for name in direct[block]:
                scale = max(1.0, np.abs(direct[block][name]).max())
                assert np.abs(mats[block][name] - direct[block][name]).max() < 1e-13 * scale, (n, block, name)


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_a_new_link_changes_only_the_rows_and_columns_of_its_ancestors(seed):
    """Adding link k: outside (ancestors of k) x (ancestors of k), plus row and column k, nothing moves."""
    m = random_tree(10, 3, seed)
    q, _, _ = random_states(m, 3, seed)
    previous = None
    for n, mats in recurrence.matrix_sequence(m, q):
        if previous is not None:
            k = n - 1
            touched = np.zeros((n - 1, n - 1), dtype=bool)
            anc = list(m.ancestors[k])
            touched[np.ix_(anc, anc)] = True
            for block in mats:
                for name, new in mats[block].items():
                    old = previous[block][name]
                    if name == "P":
                        assert np.array_equal(new[:, :n - 1][:, [i not in anc for i in range(n - 1)]],
                                              old[:, [i not in anc for i in range(n - 1)]])
                    else:
                        assert np.array_equal(new[:, :n - 1, :n - 1][:, ~touched], old[:, ~touched]), (n, block, name)
        previous = {b: {k_: np.array(v) for k_, v in ms.items()} for b, ms in mats.items()}


@pytest.mark.parametrize("mech", [random_tree(3, 2, 7), random_tree(4, 3, 8), exo5(3)], ids=lambda m: m.name)
@pytest.mark.parametrize("symbolic_parameters", [False, True])
def test_symbolic_recurrence_composes_the_same_equations_as_the_matrix_method(mech, symbolic_parameters):
    a = recurrence.compose_equations(mech, symbolic_parameters)
    b = symbolic.compose_equations(mech, symbolic_parameters)
    assert a == b


def test_symbolic_recurrence_matrices_evaluate_to_the_numeric_ones():
    m = random_tree(4, 3, 9)
    q, _, _ = random_states(m, 3, 1)
    mats = recurrence.symbolic_matrices(m)
    num = recurrence.matrices(m, q)
    from exo_bench.models.symbols import symbols_for
    import sympy as sp
    S = symbols_for(4, 3)
    for block in num:
        for name in num[block]:
            f = sp.lambdify(list(S.q), mats[block][name], modules="numpy")
            for s in range(3):
                val = np.asarray(f(*q[s]), dtype=float).reshape(num[block][name][s].shape)
                assert np.allclose(val, num[block][name][s], rtol=1e-12, atol=1e-12)
