"""Where the stride's energy goes (bench/studies/stride/evidence.py): the floor's work and the joints' negative work.

* Over a periodic stride the body's energy returns to its start, so the floor's work is minus the actuators'
  (tau . qd integrated): the two are independent sums (contact forces times point velocities; the optimiser's
  generalised forces times rates). Error model: both are trapezoidal sums over the nodes of a trapezoidal
  collocation, whose energy drift per stride is O(h^2) of the gross power; bound: 1 % of the gross work
  (integral of |tau_i qd_i|) (measured: 0.14 % human at 1.41 m/s; exo 0.014 % with its loads continuous
  across the join, 0.89 % before, trial exo-join-free, whose halves' accelerations jumped there).
* The joints' negative work from the cycle's power curves, on a hand-made case.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.bench.studies.stride import data, evidence
from exo_bench.bench.studies.stride.cycle import Curve
from exo_bench.models.mechanism.presets import human

M = human(2)


@pytest.mark.parametrize("key", [("human", 1.41), ("exo", 1.41)], ids=lambda k: f"{k[0]}-{k[1]:g}")
def test_the_floor_takes_what_the_actuators_put_in_over_a_stride(key):
    st = data.load(*key, M)
    floor = evidence.floor_work(M, st)
    actuators = float(np.trapezoid(np.einsum("kd,kd->k", st.tau, st.qd), st.t))
    gross = float(np.trapezoid(np.abs(st.tau * st.qd).sum(axis=1), st.t))
    assert floor < -10.0  # J: the floor absorbs
    assert abs(floor + actuators) <= 0.01 * gross, (floor, actuators, gross)


def test_negative_joint_work_counts_both_legs_of_the_right_legs_curves():
    bins = np.linspace(0, 1, 100, endpoint=False)
    hip = np.where(bins < 0.25, -1.0, 2.0)  # W/kg: -1 for a quarter of the cycle
    flat = np.zeros(100)
    cs = {
        "hip power": Curve("hip power", "W/kg", hip, 2 * hip),
        "knee power": Curve("knee power", "W/kg", flat, flat),
        "ankle power": Curve("ankle power", "W/kg", flat, -flat - 0.5),
    }
    ours, his = evidence.negative_joint_work(cs, (1.0, 2.0), 50.0)
    assert ours == pytest.approx(2 * 50.0 * -1.0 * 0.25 * 1.0)
    assert his == pytest.approx(2 * 50.0 * (-2.0 * 0.25 - 0.5) * 2.0)


def test_the_floors_absorbed_work_is_priced_at_w_floor():
    """On a 2-interval NLP (no solve): pricing the floor at ``w_floor`` adds ``w_floor`` times the floor's
    absorbed work per metre over body weight, its power recomputed here in numpy (contact forces of
    :func:`~exo_bench.bench.studies.stride.data.contact_forces` times the points' velocities)."""
    pytest.importorskip("casadi")
    from dataclasses import replace

    import casadi as ca

    from exo_bench.bench.studies.stride import problem, transcription
    from exo_bench.bench.studies.stride.coordinates import free_map
    from exo_bench.models.mechanism.kinematics import point_mass_velocities
    from exo_bench.models.simulation.contact import balanced_standing

    s = problem.settings_for(M, "human", 1.41, intervals=2, eps_power=10.0, w_floor=0.0)
    fm = free_map(M, balanced_standing(M))
    t, z, zd, zdd = problem.initial_guess(M, fm, s, T=0.5)
    zd[:, fm.index("root length")] -= 0.3  # the hips sink: the feet press into the floor and its damping absorbs
    f = []
    for si in (s, replace(s, w_floor=0.5)):
        nlp, node, rows = transcription.build(M, fm, si)
        full = (fm.full(z).T, fm.full(zd, rates=True).T, fm.full(zdd, rates=True).T)
        Y = np.asarray(node.map(len(z))(*full)[0]).T
        x = nlp.x0(float(t[-1]), z, zd, zdd, Y[:, rows.powers])
        f.append(float(ca.Function("f", [nlp.nlp["x"]], [nlp.nlp["f"]])(x)))
    q, qd = fm.full(z), fm.full(zd, rates=True)
    v = point_mass_velocities(M, q, qd)[:, data.contact_mask_order(M), 2, :]
    power = np.einsum("kpd,kpd->k", data.contact_forces(M, q, qd), v)
    unit = M.total_mass * M.g * s.speed
    want = 0.5 * float(np.array([0.25, 0.5, 0.25]) @ -power) / unit
    assert abs(want) > 1e-4, want
    assert f[1] - f[0] == pytest.approx(want, rel=1e-9)


def test_the_report_states_the_floor_price_and_the_springs():
    from exo_bench.bench.studies.stride import report
    from exo_bench.bench.studies.stride.data import StoredStride

    st = data.load("human", 1.41, M)
    plain = {**st.settings, "w_floor": 0.0, "spring": [0.0, 0.0, 0.0]}
    line = report.objective_line(StoredStride(**{**st.__dict__, "meta": {**st.meta, "settings": plain}}))
    assert "Also:" not in line
    mine = {**plain, "w_floor": 4.0, "spring": [0.0, 0.0, 0.5]}
    line = report.objective_line(StoredStride(**{**st.__dict__, "meta": {**st.meta, "settings": mine}}))
    assert "the work the floor absorbs (its contact's damping and friction) priced at 4 per metre" in line
    assert "passive springs about standing (N·m/kg/rad): ankle 0.5" in line and "hip 0" not in line
    # the stored numbers were picked by the checks the report then shows: it says so beside them
    assert "chosen from the trials below by the checks below" in line and "no checked source" in line
