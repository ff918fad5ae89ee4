"""The human model standing on its heels and toes (models/simulation/contact.py, models/simulation/contact.py through
``simulate(..., f_ext=...)`` and models/runtime/external_forces.py): it comes to rest carrying its weight, and every method's
inverse dynamics with the floor's ``f_ext`` returns the joint moments and rod forces that held it.

One simulation (Radau, rtol 1e-4, 2 s of standing, about 130 steps: 3-6 s on this machine, the price of
a floating model on stiff contact) is shared by the tests through a module fixture.

Error models: at rest the floor's vertical forces equal the weight plus ``sum m a_z``; the contact's
dissipation has damped the vertical modes (about 15 1/s) by 1e-6 after 1 s, and what is left is the slow
creep of the friction law, which has no stiction (models/simulation/contact.py): ``1e-3 m g`` bounds it with a
margin of 10 (measured 7e-5 at 1 s). The inverse dynamics agree to the error model of conftest.py
with the external forces' own term (tests/test_external_forces.py).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import K, assert_close, installed_methods, term_scale
from test_external_forces import external_force_scale

from exo_bench import prepare
from exo_bench.models.simulation.contact import ContactParameters
from exo_bench.models.simulation.contact import balanced_standing, centre_of_mass, ground_reaction, hold
from exo_bench.models.mechanism.presets import human
from exo_bench.models.simulation.forward_dynamics import simulate

C = ContactParameters()
G = 9.81


@pytest.fixture(scope="module")
def standing():
    m = human(2)
    q_ref = balanced_standing(m)
    q0 = q_ref.copy()
    q0[0, m.nlinks] -= (m.total_mass * G / 4 / C.hertz) ** (2 / 3)  # each sole point a quarter of the weight
    controls = hold(m, q_ref)
    model = prepare(m, "matrix-factored")
    floor = lambda t, q, qd: ground_reaction(m, q, qd, C)  # noqa: E731
    sim = simulate(model, q0, np.zeros_like(q0), (0.0, 2.0), controls, integrator="Radau", rtol=1e-4, f_ext=floor)
    assert sim.status == "ok", sim.status
    return m, model, controls, sim


def test_the_balanced_pose_has_the_centre_of_mass_over_the_middle_of_the_feet():
    m = human(2)
    q = balanced_standing(m)
    x = centre_of_mass(m, q)[0, 0]
    from exo_bench.models.mechanism.kinematics import point_mass_positions
    from exo_bench.models.simulation.contact import contact_points

    feet = point_mass_positions(m, q)[0][contact_points(m)]
    assert abs(x - 0.5 * (feet[:, 0].min() + feet[:, 0].max())) < 1e-9
    assert np.all(np.abs(feet[:, 1]) < 1e-12)  # still flat on the floor


def test_standing_comes_to_rest_with_the_floor_carrying_the_body_weight(standing):
    m, _, _, sim = standing
    late = sim.t >= 1.0
    q, qd = sim.q(m.dof)[late], sim.qd(m.dof)[late]
    fz = ground_reaction(m, q, qd, C)[..., 1].sum(axis=(1, 2))
    np.testing.assert_allclose(fz, m.total_mass * G, rtol=1e-3)
    com_z = centre_of_mass(m, q)[:, 1]
    assert np.ptp(com_z) < 1e-4  # the body no longer rises or sinks (m)
    assert np.all(np.abs(qd) < 0.05)  # what moves is the friction's slow creep (rad/s, m/s)


def test_every_methods_inverse_dynamics_with_the_floors_forces_returns_the_hold(standing):
    """Along the standing motion: every method's ``ID(q, qd, qdd, f_ext)`` agrees with Newton-Euler's numpy
    passes to the error model, and equals the hold that produced ``qdd`` (by ``FD`` with the same
    ``f_ext``) to that model times ``cond(M)``, the round trip's loss."""
    m, model, controls, sim = standing
    idx = np.linspace(0, len(sim.t) - 1, 6).astype(int)
    q, qd = sim.q(m.dof)[idx], sim.qd(m.dof)[idx]
    f = ground_reaction(m, q, qd, C)
    tau = controls(0.0, q, qd)
    qdd = model.forward_dynamics(q, qd, tau, f_ext=f)
    scale = term_scale(m, q, qd, qdd) + external_force_scale(m, q, f)
    ref = prepare(m, "newton-euler", kernel="numpy").inverse_dynamics(q, qd, qdd, f_ext=f)
    for method in installed_methods():
        if method == "lagrange":
            continue  # a 10-link derivation; the random trees of tests/test_external_forces.py cover it
        got = prepare(m, method).inverse_dynamics(q, qd, qdd, f_ext=f)
        assert_close(got, ref, scale, K, f"{method}: inverse dynamics with the floor's forces")
    cond = np.linalg.cond(model.mass_matrix(q))[:, None]
    assert_close(ref, tau, scale * cond, K, "the hold, through forward and inverse dynamics")
    assert np.all(tau[:, [0, m.nlinks]] == 0)  # the root carries nothing: O holds nothing up
