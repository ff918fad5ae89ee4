"""The symbolic matrix method: its equations and matrices are Lagrange's, exactly."""

import numpy as np
import pytest

from exo_bench.lagrange import canonical_form, derive
from exo_bench.matrix_method import numeric, symbolic
from exo_bench.models.motion import random_states
from exo_bench.models.presets import fig1, fig2a, fig2b, random_tree
from exo_bench.models.symbols import symbols_for

MODELS = [fig1(2), fig2a(2), fig2b(2), random_tree(3, 2, 3), random_tree(3, 2, 4),
          fig1(3), fig2b(3), random_tree(2, 3, 5), random_tree(3, 3, 6), random_tree(3, 3, 7)]


@pytest.mark.parametrize("mech", MODELS, ids=lambda m: m.name)
def test_composed_equations_equal_lagranges_with_symbolic_parameters(mech):
    """Difference reduced to the canonical form (expand_trig, cos^2 -> 1 - sin^2) is zero."""
    d = derive(mech, symbolic_parameters=True)
    ours = symbolic.compose_equations(mech, symbolic_parameters=True)
    assert len(ours) == mech.dof
    for a, b in zip(ours, d.equations):
        assert canonical_form(a - b, d.symbols) == 0


@pytest.mark.parametrize("mech", MODELS[3:5] + MODELS[8:], ids=lambda m: m.name)
def test_composed_equations_equal_lagranges_with_the_mechanisms_numbers(mech):
    d = derive(mech, symbolic_parameters=False)
    for a, b in zip(symbolic.compose_equations(mech), d.equations):
        assert canonical_form(a - b, d.symbols) == 0


@pytest.mark.parametrize("mech", [fig2b(2), random_tree(3, 2, 8), fig2b(3), random_tree(3, 3, 9)], ids=lambda m: m.name)
def test_every_matrix_equals_lagranges_entry_by_entry(mech):
    d = derive(mech, symbolic_parameters=True)
    ours = symbolic.matrices(mech, symbolic_parameters=True)
    for block, mats in d.matrices.items():
        for name, M in mats.items():
            for i in range(M.rows):
                for j in range(M.cols):
                    assert canonical_form(ours[block][name][i, j] - M[i, j], d.symbols) == 0, (block, name, i, j)


@pytest.mark.parametrize("n,dim,seed", [(5, 2, 1), (6, 3, 2)])
def test_lambdified_equations_equal_the_numeric_matrix_method(n, dim, seed, rel):
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 20, seed)
    f = symbolic.lambdified(m)
    tau = np.stack([np.broadcast_to(v, (20,)) for v in f(*q.T, *qd.T, *qdd.T)], -1)
    assert rel(tau, numeric.inverse_dynamics(m, q, qd, qdd)) < 1e-12


def test_equations_use_the_shared_symbols_and_only_own_rate_products():
    """The form of eq. (17): no product of rates of two different links."""
    m = random_tree(4, 3, 10)
    S = symbols_for(4, 3)
    rates = set(S.qd)
    allowed = set(S.q + S.qd + S.qdd) | {a for link in S.m for a in link} | set(S.n) | {S.g}
    for e in symbolic.compose_equations(m, symbolic_parameters=True):
        assert e.free_symbols <= allowed
        for term in e.expand().args:
            links = {str(s)[-1] for s in term.free_symbols & rates}
            assert len(links) <= 1, term
