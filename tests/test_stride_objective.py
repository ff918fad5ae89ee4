"""The stride problem's objective knobs (bench/studies/stride/transcription.py).

* the telescopic rods' work is priced at ``w_rod_work`` times the joints': raising it from 1 to 10 adds
  exactly 9 times the rods' priced work to the objective, and nothing else;
* effort divides each joint's moment by its strength: an ankle twice as strong costs a quarter.

Cheap: a 2-interval NLP, no solve.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from exo_bench.models.mechanism.presets import human

M = human(2)


@pytest.fixture(scope="module")
def small():
    """Settings of 2 intervals, the free map, and a flat-footed walk's half stride ``(T, z, zd, zdd)``."""
    pytest.importorskip("casadi")
    from exo_bench.bench.studies.stride import problem
    from exo_bench.bench.studies.stride.coordinates import free_map
    from exo_bench.models.simulation.contact import balanced_standing

    s = problem.settings_for(M, "human", 1.41, intervals=2)
    fm = free_map(M, balanced_standing(M))
    t, z, zd, zdd = problem.initial_guess(M, fm, s, T=0.5)
    zd[:, fm.index("right_leg length")] = 0.3  # the rods move, so they work
    zd[:, fm.index("left_thigh length")] = -0.2
    return s, fm, (float(t[-1]), z, zd, zdd)


def _objective(s, fm, start) -> tuple[float, np.ndarray, np.ndarray]:
    """The objective at ``start``, the node outputs ``Y (N + 1, size)`` and the effort's moments (N·m)."""
    import casadi as ca

    from exo_bench.bench.studies.stride import transcription

    nlp, node, rows = transcription.build(M, fm, s)
    T, z, zd, zdd = start
    full = (fm.full(z).T, fm.full(zd, rates=True).T, fm.full(zdd, rates=True).T)
    Y = np.asarray(node.map(len(z))(*full)[0]).T
    f = ca.Function("f", [nlp.nlp["x"]], [nlp.nlp["f"]])
    x = nlp.x0(T, z, zd, zdd, Y[:, rows.powers])
    return float(f(x)), Y, Y[:, rows.moments]


def _weights(N: int) -> np.ndarray:
    w = np.full(N + 1, 1.0 / N)
    w[[0, -1]] /= 2
    return w


def test_rod_work_is_priced_at_w_rod_work_times_the_joints(small):
    from exo_bench.bench.studies.stride import transcription

    s, fm, start = small
    s = replace(s, eps_power=10.0, w_rod_work=1.0)  # the smoothed |P|: no slack variables, the work is the powers' own
    f1, Y, _ = _objective(s, fm, start)
    f10, _, _ = _objective(replace(s, w_rod_work=10.0), fm, start)
    _, rows = transcription.node_function(M, s)
    unit = M.total_mass * M.g * s.speed
    P = Y[:, rows.powers][:, len(transcription.PRICED_JOINTS) :] / unit  # the four rods
    a = np.sqrt(P**2 + (s.eps_power / unit) ** 2)
    rods = (s.w_positive * (a + P) / 2 + s.w_negative * (a - P) / 2).sum(axis=1)
    assert np.abs(P).max() > 1e-3  # the rods do work here
    want = 9.0 * float(_weights(s.intervals) @ rods)
    assert f10 - f1 == pytest.approx(want, rel=1e-9, abs=1e-12)


def test_an_ankle_twice_as_strong_costs_a_quarter(small):
    from exo_bench.bench.studies.stride import transcription
    from exo_bench.bench.studies.stride.actuators import actuators

    s, fm, start = small
    s = replace(s, eps_power=10.0, spring=(0.0, 0.0, 0.0))  # net moments: the springs' share has its own test
    f1, _, moments = _objective(s, fm, start)
    f2, _, _ = _objective(replace(s, strength=(1.0, 1.0, 2.0)), fm, start)
    names = actuators(M, np.zeros((1, M.dof))).joint_names
    ankles = [names.index(j) for j in transcription.PRICED_JOINTS if j.endswith("ankle")]
    per_node = ((moments[:, ankles] / M.total_mass) ** 2).sum(axis=1)
    want = s.w_moment * (0.25 - 1.0) * float(_weights(s.intervals) @ per_node)
    assert abs(want) > 1e-6
    assert f2 - f1 == pytest.approx(want, rel=1e-9)
