"""The 50-digit virtual-work reference: agrees with the independent implementations and with physics."""

import mpmath
import numpy as np
import pytest
from conftest import EPS, assert_forces_agree

from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.mechanism import virtual_work as vw
from exo_bench.models.mechanism.kinematics import energy_rate
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, exo5, random_tree


@pytest.mark.parametrize("n,dim,seed", [(1, 2, 0), (3, 2, 1), (7, 2, 2), (1, 3, 3), (4, 3, 4), (8, 3, 5)])
def test_agrees_with_pinocchio_on_random_trees(n, dim, seed):
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 4, seed)
    assert_forces_agree(vw.inverse_dynamics(m, q, qd, qdd), pb.inverse_dynamics(m, q, qd, qdd), m, q, qd, qdd)


def test_power_balance_holds_to_many_digits_along_the_gait():
    """With 50-digit forces, tau . qd matches d(T+Pi)/dt up to the difference stencil's own error:
    truncation O(h^6) and rounding eps |T + Pi| / h (models.kinematics.energy_rate, h = 1e-3), the
    latter bounded here with the energy itself."""
    m = exo5(3)
    from exo_bench.models.gait.motion import gait

    f = lambda t: gait(m, t)
    t = np.linspace(0.05, 1.0, 7)
    mo = f(t)
    power = (vw.inverse_dynamics(m, mo.q, mo.qd, mo.qdd) * mo.qd).sum(1)
    rate = energy_rate(m, f, t)
    from exo_bench.models.mechanism.kinematics import _FD6, total_energy

    # the stencil sums sum|c_k| E(t + k h) / h, each energy a sum of 2 terms (T and Pi) per point
    # mass rounded once each; twice that for the truncation and the forces' own rounding
    energy = np.abs(total_energy(m, mo.q, mo.qd)).max()
    terms = 2 * 3 * m.nlinks
    bound = 2 * float(np.abs(_FD6).sum()) * terms * EPS * energy / 1e-3
    assert np.abs(power - rate).max() < bound


def test_more_digits_change_nothing_at_float64_precision():
    m = chain(12, 3, seed=4)
    q, qd, qdd = random_states(m, 2, 9)
    a = vw.inverse_dynamics(m, q, qd, qdd, dps=50)
    b = vw.inverse_dynamics(m, q, qd, qdd, dps=80)
    assert np.array_equal(a, b)


def test_mp_values_carry_the_requested_precision():
    m = random_tree(3, 3, 1)
    q, qd, qdd = random_states(m, 1, 0)
    rows = vw.inverse_dynamics_mp(m, q, qd, qdd, dps=50)
    assert all(isinstance(x, mpmath.mpf) for x in rows[0])
    with mpmath.workdps(60):
        hi = vw.inverse_dynamics_mp(m, q, qd, qdd, dps=60)[0]
        assert max(abs(x - y) for x, y in zip(rows[0], hi)) < mpmath.mpf(10) ** -45 * max(abs(x) for x in hi)
