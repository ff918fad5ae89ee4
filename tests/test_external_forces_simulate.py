"""``simulate`` with external forces ``f_ext(t, q, qd)`` (issue 37): a spring from the end of the last link
to a fixed anchor, a conservative force, so ``T + Pi + k/2 |P - A|^2`` stays constant along the
integration (its drift is the integrator's: DOP853 at rtol 1e-10 drifts by 8.5e-11 relative over
0.5 s here; the bound 1e-7 is far below what a wrong sign of Q gives, 7.9e3 relative); forces that cancel the weight hold a tree at rest; bad ``f_ext`` refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.mechanism.kinematics import point_mass_positions, total_energy
from exo_bench.models.mechanism.presets import random_tree
from exo_bench.models.simulation.forward_dynamics import simulate

MECH = random_tree(3, 3, 5)
K_SPRING = 400.0
ANCHOR = np.array([0.3, -0.2, -0.4])


def _spring(t, q, qd):
    f = np.zeros((q.shape[0], MECH.nlinks, 3, MECH.dim))
    f[:, -1, 2] = -K_SPRING * (point_mass_positions(MECH, q)[:, -1, 2] - ANCHOR)
    return f


def _energy(q, qd):
    stretch = point_mass_positions(MECH, q)[:, -1, 2] - ANCHOR
    return total_energy(MECH, q, qd) + 0.5 * K_SPRING * (stretch**2).sum(axis=1)


def _start():
    n = MECH.nlinks
    q0 = np.r_[np.linspace(0.2, 1.0, n), np.linspace(-0.3, 0.4, n), np.full(n, 0.6)]
    return q0, np.r_[np.full(2 * n, 0.5), np.zeros(n)]


def test_a_spring_force_conserves_its_energy():
    model = prepare(MECH, "newton-euler")
    q0, qd0 = _start()
    zero = lambda t, q, qd: np.zeros_like(q)
    sim = simulate(model, q0, qd0, (0.0, 0.5), zero, rtol=1e-10, f_ext=_spring)
    assert sim.ok, sim.status
    E = _energy(sim.q(MECH.dof), sim.qd(MECH.dof))
    drift = np.abs(E - E[0]).max() / np.abs(E[0])
    assert drift < 1e-7, drift
    free = simulate(model, q0, qd0, (0.0, 0.5), zero, rtol=1e-10)  # the spring did something
    assert np.abs(free.y[-1] - sim.y[-1]).max() > 1e-2


def test_forces_that_cancel_the_weight_hold_it_at_rest():
    model = prepare(MECH, "newton-euler")
    q0, _ = _start()
    lift = lambda t, q, qd: np.broadcast_to(
        np.concatenate([np.zeros((MECH.nlinks, 3, 2)), (MECH.mass_array * MECH.g)[..., None]], axis=-1),
        (q.shape[0], MECH.nlinks, 3, 3),
    )
    sim = simulate(model, q0, np.zeros_like(q0), (0.0, 0.5), lambda t, q, qd: np.zeros_like(q), f_ext=lift)
    assert sim.ok and np.abs(sim.y[-1] - sim.y[0]).max() < 1e-12


def test_bad_f_ext_is_refused_by_name():
    model = prepare(MECH, "newton-euler")
    q0, qd0 = _start()
    zero = lambda t, q, qd: np.zeros_like(q)
    with pytest.raises(ValueError, match="simulate: field 'f_ext': expected a function"):
        simulate(model, q0, qd0, (0.0, 1.0), zero, f_ext=np.zeros((3, 3, 3)))
    with pytest.raises(ValueError, match="field 'jacobian': expected 'finite-difference' with f_ext"):
        simulate(model, q0, qd0, (0.0, 1.0), zero, integrator="Radau", jacobian="analytic", f_ext=_spring)
    nan = lambda t, q, qd: np.full((MECH.nlinks, 3, 3), np.nan)
    sim = simulate(model, q0, qd0, (0.0, 1.0), zero, f_ext=nan)
    assert "field 'f_ext': sample 0, link 1" in sim.status and "expected a finite force" in sim.status
