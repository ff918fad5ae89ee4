"""The recurrence (22)-(26) for trees, against oracles that do not share its closed forms:
Pinocchio's RNEA, Lagrange's equations (numeric and symbolic), and the structure of eq. (24)."""

import numpy as np
import pytest
from conftest import assert_forces_agree

from exo_bench import prepare
from exo_bench.lagrange import canonical_form, derive
from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.matrix_method import recurrence
from exo_bench.matrix_method import symbolic
from exo_bench.bench.studies.errata import prefix, prefix_states
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, fig2b, random_tree

TREES = [(1 + s % 6, 2 if (s // 6) % 2 == 0 else 3, s) for s in range(100)]


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_recurrence_agrees_with_pinocchio_and_lagrange_on_random_trees(n, dim, seed):
    """Within the float64 error model of tests/conftest.py."""
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 8, seed)
    tau = prepare(m, "recurrence").inverse_dynamics(q, qd, qdd)
    assert_forces_agree(tau, prepare(m, "pinocchio").inverse_dynamics(q, qd, qdd), m, q, qd, qdd, what="pinocchio")
    if n <= 3:
        assert_forces_agree(tau, prepare(m, "lagrange").inverse_dynamics(q, qd, qdd), m, q, qd, qdd, what="lagrange")


@pytest.mark.parametrize("dim,seed", [(2, 1), (3, 2), (3, 3)])
def test_every_intermediate_model_of_the_recurrence_is_pinocchios_for_every_n_up_to_20(dim, seed):
    """Eq. (23): the matrices after adding link n are those of the first n links: their forces are
    Pinocchio's RNEA on the model of the first n links (each prefix a model of its own)."""
    m = random_tree(20, dim, seed)
    q, qd, qdd = random_states(m, 4, seed)
    for n, mats in recurrence.matrix_sequence(m, q):
        sub = prefix(m, n)
        qs, qds, qdds = (prefix_states(m, x, n) for x in (q, qd, qdd))
        tau = numeric.generalised_forces(sub, mats, qds, qdds)
        assert_forces_agree(
            tau, prepare(sub, "pinocchio").inverse_dynamics(qs, qds, qdds), sub, qs, qds, qdds, what=f"n={n}"
        )


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
                        assert np.array_equal(
                            new[:, : n - 1][:, [i not in anc for i in range(n - 1)]],
                            old[:, [i not in anc for i in range(n - 1)]],
                        )
                    else:
                        assert np.array_equal(new[:, : n - 1, : n - 1][:, ~touched], old[:, ~touched]), (n, block, name)
        previous = {b: {k_: np.array(v) for k_, v in ms.items()} for b, ms in mats.items()}


@pytest.mark.parametrize("mech", [random_tree(3, 2, 7), fig2b(3), random_tree(3, 3, 8)], ids=lambda m: m.name)
@pytest.mark.parametrize("symbolic_parameters", [False, True])
def test_symbolic_recurrence_composes_lagranges_equations(mech, symbolic_parameters):
    """The equations grown link by link equal Lagrange II derived from T and Pi of the point
    masses (lagrange.derive), exactly: the difference's canonical form is zero."""
    d = derive(mech, symbolic_parameters=symbolic_parameters)
    ours = recurrence.compose_equations(mech, symbolic_parameters)
    assert len(ours) == mech.dof
    for a, b in zip(ours, d.equations):
        assert canonical_form(a - b, d.symbols) == 0


@pytest.mark.parametrize("mech", [random_tree(4, 3, 9), exo5(3)], ids=lambda m: m.name)
def test_symbolic_recurrence_evaluates_to_pinocchios_forces(mech):
    """The symbolic recurrence's equations, lambdified, against Pinocchio's RNEA (models too large
    for an exact comparison with Lagrange within CI's time)."""
    q, qd, qdd = random_states(mech, 5, 1)
    f = symbolic.lambdified(mech, compose=recurrence.compose_equations)
    tau = np.stack([np.broadcast_to(np.asarray(v, dtype=float), (5,)) for v in f(*q.T, *qd.T, *qdd.T)], -1)
    assert_forces_agree(tau, prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd), mech, q, qd, qdd)
