"""The stride problem's passive joint moments and floor parameters (bench/studies/stride/passive.py, data.contact_of).

* Anderson and Pandy's end-range moments: near zero standing, restoring beyond each end of the range;
* the objective prices the active moment, the net moment less the passive element's: with a linear ankle
  spring and work unpriced, the objective changes by exactly the effort of (M - M_p) less that of M;
* a stride's contact parameters are the defaults with its settings' ``contact`` fields changed.

Cheap: a 2-interval NLP, no solve.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from exo_bench.bench.studies.stride import data
from exo_bench.bench.studies.stride.passive import passive_moment
from exo_bench.models.simulation.contact import DEFAULT_CONTACT
from exo_bench.models.mechanism.presets import human

M = human(2)


class _S:
    passive = "anderson-pandy"
    spring = (0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "joint, theta_0, inside, beyond, sign",
    [
        ("hip", 0.0, 0.0, 1.81 + 0.2, -1.0),  # flexed past 104 degrees: pulled back (extending)
        ("hip", 0.0, 0.0, -0.6981 - 0.2, 1.0),  # extended past 40 degrees: pushed forward (flexing)
        ("knee", 0.0, 0.0, 0.13 + 0.1, -1.0),  # hyperextended: pushed into flexion (theta = -flexion)
        ("ankle", 1.18, 1.18, 1.18 + 0.52 + 0.1, -1.0),  # dorsiflexed past 30 degrees: plantarflexing
    ],
)
def test_anderson_pandy_moments_vanish_standing_and_restore_beyond_the_range(joint, theta_0, inside, beyond, sign):
    standing = passive_moment(_S(), joint, np.array(inside), theta_0, 56.7, np.exp)
    out = passive_moment(_S(), joint, np.array(beyond), theta_0, 56.7, np.exp)
    assert abs(standing) < 0.2  # N·m: against stance moments of 30-90 N·m
    assert sign * out > 2.0, (joint, float(out))


def test_the_objective_prices_the_net_moment_less_the_passive_one():
    pytest.importorskip("casadi")
    import casadi as ca

    from exo_bench.bench.studies.stride import problem, transcription
    from exo_bench.bench.studies.stride.actuators import actuators
    from exo_bench.bench.studies.stride.coordinates import free_map
    from exo_bench.models.simulation.contact import balanced_standing, joints

    s = problem.settings_for(
        M, "human", 1.41, intervals=2, eps_power=10.0, w_positive=0.0, w_negative=0.0, spring=(0.0, 0.0, 0.0)
    )
    fm = free_map(M, balanced_standing(M))
    t, z, zd, zdd = problem.initial_guess(M, fm, s, T=0.5)
    z[:, fm.index("right_foot angle")] += np.array([0.1, -0.05, 0.2])  # the ankles away from standing
    k = 3.0  # N·m/kg/rad at the ankles
    f = []
    for si in (s, replace(s, spring=(0.0, 0.0, k))):
        nlp, node, rows = transcription.build(M, fm, si)
        full = (fm.full(z).T, fm.full(zd, rates=True).T, fm.full(zdd, rates=True).T)
        Y = np.asarray(node.map(len(z))(*full)[0]).T
        x = nlp.x0(float(t[-1]), z, zd, zdd, Y[:, rows.powers])
        f.append(float(ca.Function("f", [nlp.nlp["x"]], [nlp.nlp["f"]])(x)))
    q = fm.full(z)
    q0 = balanced_standing(M)[0]
    names = actuators(M, np.zeros((1, M.dof))).joint_names
    js, m = joints(M), M.total_mass
    want = np.zeros(len(z))
    for j in transcription.PRICED_JOINTS:
        if j.endswith("ankle"):
            i = names.index(j)
            link, ref, _ = js[i]
            mp = -k * m * ((q[:, link] - q[:, ref]) - (q0[link] - q0[ref]))  # the spring, conjugate to theta
            mom = Y[:, rows.moments][:, i]
            want += ((mom - mp) / m) ** 2 - (mom / m) ** 2
    w = np.array([0.25, 0.5, 0.25])  # trapezoidal weights of 2 intervals over the half stride
    expected = s.w_moment * float(w @ want)
    assert abs(expected) > 1e-4
    assert f[1] - f[0] == pytest.approx(expected, rel=1e-9)


def test_a_strides_contact_is_the_default_with_its_fields_changed():
    assert data.contact_of({}) is DEFAULT_CONTACT
    assert data.contact_of({"contact": {}}) is DEFAULT_CONTACT
    c = data.contact_of({"contact": {"dissipation": 0.5667}})
    assert c.dissipation == 0.5667 and c.stiffness == DEFAULT_CONTACT.stiffness
    with pytest.raises(ValueError, match="settings.contact.*'heel'"):
        data.contact_of({"contact": {"heel": 1.0}})


def test_the_join_pairs_each_load_with_its_mirror_image():
    pytest.importorskip("casadi")
    from exo_bench.bench.studies.stride.actuators import PRICED_JOINTS, actuators, join_pairs

    eye = actuators(M, np.eye(M.dof))
    (ja, jb), (ra, rb) = join_pairs(M)
    assert [eye.joint_names[i] for i in ja] == list(PRICED_JOINTS)
    assert [eye.joint_names[i] for i in jb] == [*PRICED_JOINTS[3:], *PRICED_JOINTS[:3]]
    assert [eye.rod_names[i] for i in rb] == ["left_thigh", "left_leg", "right_thigh", "right_leg"]
    assert sorted(ra) == sorted(rb) and [eye.rod_names[i] for i in ra][0] == "right_thigh"
