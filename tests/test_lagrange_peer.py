"""Our Lagrange II against sympy.physics.mechanics (LagrangesMethod and KanesMethod) built
independently on the same mechanisms, n <= 2, 2D and 3D, serial and reversed second links."""

import numpy as np
import pytest
import sympy as sp
from conftest import assert_forces_agree

from exo_bench.lagrange import canonical_form, derive
from exo_bench.lagrange.derivation import parameter_values
from exo_bench.lagrange.peer import peer_equations
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import fig1, fig2a, fig2b, random_tree

CASES = [
    (fig1(2), "lagrange"),
    (fig2a(2), "lagrange"),
    (fig2b(2), "lagrange"),
    (fig2b(2), "kane"),
    (random_tree(2, 2, 71), "kane"),
    (fig1(3), "lagrange"),
    (fig1(3), "kane"),
    (fig2a(3), "kane"),
    (fig2b(3), "lagrange"),
    (fig2b(3), "kane"),
    (random_tree(2, 3, 73), "kane"),
]


@pytest.mark.parametrize("m,kind", CASES, ids=[f"{m.name}-{k}" for m, k in CASES])
def test_peer_equations_equal_ours(m, kind):
    ours = derive(m, symbolic_parameters=True)
    theirs = peer_equations(m, kind, symbolic_parameters=True)
    S = ours.symbols
    assert len(theirs) == m.dof
    # exactly, as polynomials in sines and cosines (normal form modulo sin^2 + cos^2 = 1) ...
    assert all(canonical_form(a - b, S) == 0 for a, b in zip(ours.equations, theirs))
    # ... and numerically at random states with the mechanism's numbers
    vals = parameter_values(m, S)
    num = [e.xreplace(vals) for e in theirs]
    q, qd, qdd = random_states(m, 10, 7)
    args = S.q + S.qd + S.qdd
    f = lambda eqs: np.stack(
        [np.broadcast_to(sp.lambdify(args, e, "numpy")(*q.T, *qd.T, *qdd.T), (10,)) for e in eqs], -1
    )
    a, b = f(derive(m).equations), f(num)
    assert_forces_agree(a, b, m, q, qd, qdd)


def test_peer_sees_the_branch_sign():
    """The reversed second link (Fig. 2b) changes the peer's equations: the comparison can fail."""
    S = derive(fig2a(2), symbolic_parameters=True).symbols
    a = peer_equations(fig2a(2), "kane", symbolic_parameters=True)
    b = peer_equations(fig2b(2), "kane", symbolic_parameters=True)
    assert canonical_form(a[1] - b[1], S) != 0


def test_unknown_peer_kind_is_a_value_error():
    with pytest.raises(ValueError, match="kind"):
        peer_equations(fig1(2), "hamilton")
