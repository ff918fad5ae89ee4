"""The human model's actuators (bench/studies/stride/actuators.py): joint moments, rod forces and
residuals rebuild the generalised forces; their powers balance the energy; the work terms split it.

Error models: the split and rebuild are sums of at most five terms per row (1e-12 of the largest force
holds with a wide margin); the power balance is conftest's (:data:`POWER_BALANCE_TOL`, a sixth-order
difference of the energy).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import POWER_BALANCE_TOL

from exo_bench import prepare
from exo_bench.bench.studies.stride.actuators import actuators, powers, work_terms
from exo_bench.models.mechanism.kinematics import energy_rate
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.simulation.contact import joints
from exo_bench.models.mechanism.presets import exo5, human

M = human(2)


def test_moments_forces_and_residuals_rebuild_the_generalised_forces():
    tau = np.random.default_rng(1).normal(0, 100, (7, M.dof))
    act = actuators(M, tau)
    assert act.joint_names == tuple(f"{s}_{j}" for s in ("right", "left") for j in ("hip", "knee", "ankle", "arch"))
    n = M.nlinks
    back = np.zeros_like(tau)
    for k, (link, ref, _) in enumerate(joints(M)):
        back[:, link] += act.moments[:, k]
        back[:, ref] -= act.moments[:, k]
    back[:, M.names.index("hat")] += act.residuals[:, 0]
    back[:, M.names.index("root")] += act.residuals[:, 1]
    back[:, n + M.names.index("root")] = act.residuals[:, 2]
    back[:, n + np.array([M.names.index(r) for r in act.rod_names])] = act.forces
    np.testing.assert_allclose(back, tau, rtol=0, atol=1e-12 * np.abs(tau).max())


def test_actuator_and_residual_powers_balance_the_energy_along_a_motion():
    f = lambda t: smooth_random_motion(M, t, seed=5)  # noqa: E731
    t = np.linspace(0.0, 3.0, 40)
    mo = f(t)
    tau = prepare(M, "newton-euler", kernel="numpy").inverse_dynamics(mo.q, mo.qd, mo.qdd)
    pj, pr, pres = powers(M, actuators(M, tau), mo.qd)
    total = pj.sum(1) + pr.sum(1) + pres.sum(1)
    rate = energy_rate(M, f, t)
    assert np.abs(total - rate).max() <= POWER_BALANCE_TOL * np.abs(rate).max()
    assert np.abs(pres).max() > 0  # an arbitrary motion needs the residuals: they are reported, not dropped


def test_work_terms_split_the_net_work_and_smoothing_only_adds():
    t = np.linspace(0, 1, 201)
    p = np.stack([np.sin(2 * np.pi * t) * 100 + 20, -np.ones_like(t) * 5], axis=1)
    pos, neg = work_terms(p, t)
    np.testing.assert_allclose(pos - neg, np.trapezoid(p, t, axis=0), rtol=1e-12)
    assert np.all(pos >= 0) and np.all(neg >= 0) and neg[1] == pytest.approx(5.0) and pos[1] == 0
    spos, sneg = work_terms(p, t, eps=1.0)
    np.testing.assert_allclose(spos - sneg, pos - neg, rtol=1e-12)
    assert np.all(spos >= pos) and np.all(spos - pos <= 0.5 * 1.0 * (t[-1] - t[0]) + 1e-12)


def test_only_the_2d_human_has_these_actuators():
    with pytest.raises(ValueError, match="expected the 2D human preset"):
        actuators(exo5(2), np.zeros((1, exo5(2).dof)))
