"""The symbolic matrix method: its equations and matrices are Lagrange's, exactly, and those of an
independent sympy.physics.mechanics model (LagrangesMethod, KanesMethod)."""

import numpy as np
import pytest
from conftest import assert_forces_agree

from exo_bench import prepare
from exo_bench.lagrange import canonical_form, derive
from exo_bench.lagrange.peer import peer_equations
from exo_bench.matrix_method import symbolic
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import fig1, fig2a, fig2b, random_tree
from exo_bench.models.mechanism.symbols import symbols_for

MODELS = [
    fig1(2),
    fig2a(2),
    fig2b(2),
    random_tree(3, 2, 3),
    random_tree(3, 2, 4),
    fig1(3),
    fig2b(3),
    random_tree(2, 3, 5),
    random_tree(3, 3, 6),
    random_tree(3, 3, 7),
]


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


PEER_CASES = [
    (fig2b(2), "lagrange"),
    (random_tree(3, 2, 11), "kane"),
    (fig2b(3), "kane"),
    (random_tree(2, 3, 73), "kane"),
]


@pytest.mark.parametrize("mech,kind", PEER_CASES, ids=[f"{m.name}-{k}" for m, k in PEER_CASES])
def test_composed_equations_equal_sympy_mechanics(mech, kind):
    """An oracle derived another way: frames, points and particles of sympy.physics.mechanics run
    through LagrangesMethod or KanesMethod (lagrange/peer.py shares no code with the matrix method);
    equal as polynomials in the sines and cosines, with symbolic masses."""
    ours = symbolic.compose_equations(mech, symbolic_parameters=True)
    theirs = peer_equations(mech, kind, symbolic_parameters=True)
    S = derive(mech, symbolic_parameters=True).symbols
    assert len(theirs) == len(ours) == mech.dof
    for k, (a, b) in enumerate(zip(ours, theirs)):
        assert canonical_form(a - b, S) == 0, k


@pytest.mark.parametrize("n,dim,seed", [(5, 2, 1), (6, 3, 2)])
def test_lambdified_equations_give_pinocchios_forces(n, dim, seed):
    """Larger trees than an exact comparison allows in CI: the composed equations, lambdified,
    against Pinocchio's RNEA within the error model of tests/conftest.py."""
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 20, seed)
    f = symbolic.lambdified(m)
    tau = np.stack([np.broadcast_to(v, (20,)) for v in f(*q.T, *qd.T, *qdd.T)], -1)
    assert_forces_agree(tau, prepare(m, "pinocchio").inverse_dynamics(q, qd, qdd), m, q, qd, qdd)


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
