"""The human-proportioned preset with feet (models/mechanism/presets.py ``human``, ``human_standing``).

Oracles: Winter's fractions (models/mechanism/anthropometry.py) and the point masses' positions from
models/mechanism/kinematics.py, which knows nothing of the preset. Error model: positions are sums of at most
five rod vectors of closed-form lengths and angles (a few roundings each), masses closed forms of
table numbers: 1e-12 relative (1e-12 m absolute for positions at the floor) holds with a wide margin.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_bench.models.mechanism import anthropometry as a
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.engines.mjcf import to_mjcf
from exo_bench.models.mechanism.presets import PRESETS, human, human_standing, preset_descriptions
from exo_bench.models.engines.urdf import to_urdf

BODIES = [(56.7, 1.75), (80.0, 1.62)]
LINK = {name: i for i, name in enumerate(human().names)}


def _height_and_forward(mech, stature):
    P = point_mass_positions(mech, human_standing(mech, stature))[0]
    return P[..., -1], P[..., 0] - P[0, 2, 0]  # forward of the hips


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize(("body_mass", "stature"), BODIES)
def test_total_mass_is_the_body_mass_and_each_segment_winters_share(dim, body_mass, stature):
    m = human(dim, body_mass, stature)
    assert math.isclose(m.total_mass, body_mass, rel_tol=1e-12)
    share = m.mass_array.sum(1) / body_mass
    assert share[LINK["root"]] == 0
    assert math.isclose(share[LINK["hat"]], 0.678, rel_tol=1e-12)
    for side in ("right", "left"):
        assert math.isclose(share[LINK[f"{side}_thigh"]], 0.100, rel_tol=1e-12)
        assert math.isclose(share[LINK[f"{side}_leg"]], 0.0465, rel_tol=1e-12)
        foot = share[LINK[f"{side}_foot"]] + share[LINK[f"{side}_heel"]]
        assert math.isclose(foot, 0.0145, rel_tol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize(("body_mass", "stature"), BODIES)
def test_standing_height_is_the_stature_with_winters_joint_heights(dim, body_mass, stature):
    m = human(dim, body_mass, stature)
    z, x = _height_and_forward(m, stature)
    assert math.isclose(z.max(), stature, rel_tol=1e-12) and math.isclose(z[LINK["hat"], 2], stature, rel_tol=1e-12)
    for side in ("right", "left"):
        thigh, leg = LINK[f"{side}_thigh"], LINK[f"{side}_leg"]
        assert math.isclose(z[thigh, 0], a.HIP_HEIGHT * stature, rel_tol=1e-12)
        assert math.isclose(z[leg, 0], a.KNEE_HEIGHT * stature, rel_tol=1e-12)
        assert math.isclose(z[leg, 2], a.ANKLE_HEIGHT * stature, rel_tol=1e-12)
        toe, heel = LINK[f"{side}_foot"], LINK[f"{side}_heel"]
        assert abs(z[toe, 2]) < 1e-12 and abs(z[heel, 2]) < 1e-12  # flat on the floor
        assert math.isclose(x[toe, 2], a.TOE_FORWARD * stature, rel_tol=1e-12)
        assert math.isclose(x[heel, 2], a.HEEL_FORWARD * stature, rel_tol=1e-12)


@pytest.mark.parametrize("seg", ["thigh", "leg", "foot"])
def test_each_segments_centre_of_mass_is_winters_fraction_from_its_proximal_joint(seg):
    m = human(2)
    i = LINK[f"right_{seg}"]
    P = point_mass_positions(m, human_standing(m))[0, i]
    masses = m.mass_array[i].copy()
    if seg == "foot":  # the heel's 10 % came off the foot rod's ankle mass: put it back for Winter's foot
        masses[0] += m.mass_array[LINK["right_heel"]].sum()
    com = masses @ P / masses.sum()
    along = np.linalg.norm(com - P[0]) / np.linalg.norm(P[2] - P[0])
    assert math.isclose(along, {"thigh": 0.433, "leg": 0.433, "foot": 0.5}[seg], rel_tol=1e-12)


def test_the_preset_is_listed_and_the_exporters_accept_it():
    for dim in (2, 3):
        key = f"human-{dim}d"
        assert PRESETS[key]() == human(dim)
        assert "human-proportioned walker with feet" in preset_descriptions()[key]
        assert to_urdf(human(dim)).count("<link") > 0 and to_mjcf(human(dim)).count("<body") > 0


def test_the_cli_lists_the_human_presets(capsys):
    from exo_bench.bench.cli import app

    assert app.main(["presets"]) == 0
    out = capsys.readouterr().out
    assert "human-2d   2D, 10 link(s)" in out and "human-3d   3D, 10 link(s)" in out


@pytest.mark.parametrize("dim", [2, 3])
def test_the_model_floats_unheld_it_falls_at_g(dim):
    """The root rod is massless and its generalised forces zero: O holds nothing, so with no forces at all
    the centre of mass falls at g from any state at rest. Point accelerations at rest are ``J qdd``, by a
    central difference along ``qdd`` (truncation ``O(h^2)`` ~ 1e-10, rounding ``eps / h`` ~ 1e-11: 1e-7 of
    g holds with a margin)."""
    from exo_bench import prepare

    m = human(dim)
    noise = np.random.default_rng(dim).normal(0, 0.1, (1, m.dof))
    noise[:, -m.nlinks :] *= 0.1  # rods within 3 cm of their lengths; angles off the 3D chart's poles
    q = human_standing(m) + noise
    qdd = prepare(m, "matrix-factored").forward_dynamics(q, np.zeros_like(q), np.zeros_like(q))
    h = 1e-5
    acc = (point_mass_positions(m, q + h * qdd) - point_mass_positions(m, q - h * qdd)) / (2 * h)
    com = np.einsum("lk,slkd->sd", m.mass_array, acc) / m.total_mass
    want = np.zeros(dim)
    want[-1] = -m.g
    np.testing.assert_allclose(com[0], want, rtol=0, atol=1e-7 * m.g)
