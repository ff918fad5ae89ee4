"""Winter's anthropometric numbers in models/mechanism/anthropometry.py against the public transcriptions it cites,
and the human model built from them against the body it is asked for.

Oracles: the transcribed rows below, copied from their files (repository, path and commit given), not
from the module; the parallel-axis theorem, which ties each row's three radii of gyration together;
the point masses' positions from models/mechanism/kinematics.py. Error model: the table is given to three
digits, so the parallel-axis check holds to the last digit's rounding (0.0005 on each radius, about
1e-3 on the squares); masses and heights are closed forms of a few table numbers (1e-12 relative).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_bench.models.mechanism import anthropometry as a
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.mechanism.presets import human, human_standing

#: BMClab/BMC data/BSP_DempsterWinter.txt (commit bb70ec694c7d7db237eb2a131a8cf37183d7e1f4), Winter's
#: Table 4.1: mass / body mass, centre of mass from the proximal end and from the distal end, radius of
#: gyration about the centre of mass, the proximal end, the distal end (fractions of the segment length).
TABLE_4_1 = {
    "foot": (0.0145, 0.5, 0.5, 0.475, 0.69, 0.69),
    "leg": (0.0465, 0.433, 0.567, 0.302, 0.528, 0.643),
    "thigh": (0.1, 0.433, 0.567, 0.323, 0.54, 0.653),
    "HAT": (0.678, 0.626, 0.374, 0.496, 0.798, 0.621),
}
#: dpfens/PyExPhys pyexphys/anthropometry.py (commit 89d19374d31d44a59e86e253731ea0d48ea25666), Winter's
#: Fig. 4.1: heights above the floor and the foot's length, fractions of the stature.
FIG_4_1 = {"hips": 0.530, "knee": 0.285, "ankle": 0.039, "shoulders": 0.818, "foot length": 0.152}

SEGMENTS = {"foot": a.FOOT, "leg": a.LEG, "thigh": a.THIGH, "HAT": a.HAT}


@pytest.mark.parametrize("name", TABLE_4_1)
def test_each_row_is_the_transcribed_table(name):
    mass, prox, dist, rho, rho_prox, rho_dist = TABLE_4_1[name]
    seg = SEGMENTS[name]
    assert (seg.mass, seg.com, seg.gyration) == (mass, prox, rho)
    assert math.isclose(prox + dist, 1.0)
    # the radii about the ends are those about the centre of mass moved by the parallel-axis theorem
    assert abs(rho_prox**2 - (rho**2 + prox**2)) < 1.5e-3, name
    assert abs(rho_dist**2 - (rho**2 + dist**2)) < 1.5e-3, name


def test_the_lengths_are_the_transcribed_figure():
    assert a.HIP_HEIGHT == FIG_4_1["hips"] and a.KNEE_HEIGHT == FIG_4_1["knee"]
    assert a.ANKLE_HEIGHT == FIG_4_1["ankle"] and a.SHOULDER_HEIGHT == FIG_4_1["shoulders"]
    assert a.FOOT_LENGTH == FIG_4_1["foot length"]
    assert math.isclose(a.THIGH.length, FIG_4_1["hips"] - FIG_4_1["knee"])
    assert math.isclose(a.LEG.length, FIG_4_1["knee"] - FIG_4_1["ankle"])
    assert math.isclose(a.HAT.length, FIG_4_1["shoulders"] - FIG_4_1["hips"])


@pytest.mark.parametrize(("body_mass", "stature"), [(56.7, 1.75), (92.0, 1.88)])
def test_the_model_weighs_the_body_stands_its_stature_and_carries_the_tables_shares(body_mass, stature):
    mech = human(2, body_mass, stature)
    table = {k: v[0] for k, v in TABLE_4_1.items()}
    assert math.isclose(table["HAT"] + 2 * (table["thigh"] + table["leg"] + table["foot"]), 1.0)
    assert math.isclose(mech.total_mass, body_mass, rel_tol=1e-12)
    per_link = dict(zip(mech.names, mech.mass_array.sum(axis=1) / body_mass))
    assert math.isclose(per_link["hat"], table["HAT"], rel_tol=1e-12)
    for side in ("right", "left"):
        assert math.isclose(per_link[f"{side}_thigh"], table["thigh"], rel_tol=1e-12)
        assert math.isclose(per_link[f"{side}_leg"], table["leg"], rel_tol=1e-12)
        foot = per_link[f"{side}_foot"] + per_link[f"{side}_heel"]  # the heel rod takes 10 % of the foot
        assert math.isclose(foot, table["foot"], rel_tol=1e-12)
    P = point_mass_positions(mech, human_standing(mech, stature))[0]
    hat = mech.names.index("hat")
    height = P[hat, 2, -1] - P[..., -1].min()  # top of the head above the lowest contact point
    assert math.isclose(height, stature, rel_tol=1e-12)
    hips = P[hat, 0, -1]
    assert math.isclose(hips, FIG_4_1["hips"] * stature, rel_tol=1e-12)
    shoulder = hips + (FIG_4_1["shoulders"] - FIG_4_1["hips"]) * stature
    centre = hips + TABLE_4_1["HAT"][1] * (shoulder - hips)  # HAT's centre of mass, Table 4.1's way
    m = mech.mass_array[hat]
    assert math.isclose(float(m @ P[hat, :, -1]) / m.sum(), centre, rel_tol=1e-12)
    assert np.isclose(P[..., -1].min(), 0.0, atol=1e-12)
