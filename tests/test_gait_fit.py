"""The shipped gait (winter-fit-v1): its constraints re-checked on the stored constants (not the
optimiser), its documentation checked against what it achieves, and Winter's tables read back."""

from __future__ import annotations

import zipfile

import numpy as np
import pytest

from exo_bench.bench.studies.scenes import load_scene
from exo_bench.models.gait import gait_fit
from exo_bench.models.gait.gait_fit import CLEARANCE, LATERAL_BOUND, SWING_LINKS, check_gait, describe, sagittal_angles
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.gait.motion import GAITS, PAPER_ASSUMED_V1, GaitParams, gait
from exo_bench.models.gait.normative import HEEL_CONTACT, NEXT_HEEL_CONTACT, WINTER, winter_appendix
from exo_bench.models.mechanism.presets import exo5

#: Stored parameters are rounded to 1e-4 (rad, m): that moves a point mass by at most about
#: 1e-4 * (sum of rod lengths, 2.2 m) = 0.2 mm from the fitted motion.
ROUNDING = 2e-4


@pytest.fixture(scope="module")
def shipped():
    return check_gait(GaitParams())


def test_no_point_mass_of_the_swing_leg_goes_below_the_floor_in_the_shipped_gait(shipped):
    assert shipped.lowest_swing_point >= 0.0
    assert shipped.lowest_swing_point >= CLEARANCE - ROUNDING  # the fit's margin survives rounding


def test_the_shipped_scene_samples_keep_the_swing_leg_above_the_floor():
    scene = load_scene("exo5-3d")
    mo = scene.build_motion()
    P = point_mass_positions(scene.mechanism, mo.q)
    assert P[:, list(SWING_LINKS)][..., 2].min() >= 0.0
    assert scene.motion["params"] == GaitParams() == GAITS["winter-fit-v1"]


def test_the_shipped_gait_keeps_every_point_mass_near_the_sagittal_plane(shipped):
    assert shipped.lateral <= LATERAL_BOUND + ROUNDING


def test_the_cadence_is_winters(shipped):
    assert GaitParams().T == WINTER.stride_time.value
    assert 100.0 <= shipped.cadence <= 130.0


def test_in_the_first_half_period_the_stance_leg_turns_forward_and_the_swing_leg_swings_forward():
    """The direction of walking (+x): the stance shank and thigh lean further forward (their angle
    from +x falls), the swing thigh and shank swing to the front (their angle rises)."""
    p = GaitParams()
    th = sagittal_angles(gait(exo5(3), np.array([0.0, p.T / 2]), p).q)
    assert th[1, 0] < th[0, 0] and th[1, 1] < th[0, 1]
    assert th[1, 2] > th[0, 2] and th[1, 3] > th[0, 3]


def test_the_documented_fit_is_what_the_stored_parameters_achieve():
    doc = " ".join(GaitParams.__doc__.split())
    assert " ".join(describe(GaitParams()).split()) in doc


def test_the_documented_residual_of_the_fit_is_the_objective_of_the_stored_parameters(shipped):
    """The docstring's objective (365) and its angle part: each link's share is its RMS squared,
    because each link's residuals are weighted by 1/sqrt(frames) (1 deg scale)."""
    assert round(gait_fit.objective(GaitParams())) == 365
    assert "objective of 365" in " ".join(GaitParams.__doc__.split())
    angles = sum(r**2 for r in shipped.rms) / gait_fit.ANGLE_SCALE**2
    lengths = sum(
        ((a - b) / gait_fit.LENGTH_SCALE) ** 2 for a, b in zip(GaitParams().l_star, gait_fit.REST_LENGTHS[:4])
    )
    assert gait_fit.objective(GaitParams()) == pytest.approx(
        angles + lengths + (GaitParams().l / gait_fit.STRETCH_SCALE) ** 2, rel=1e-3
    )


def test_the_fit_follows_winters_curves_closer_than_the_paper_assumed_gait(shipped):
    old = check_gait(PAPER_ASSUMED_V1)
    assert sum(shipped.rms) < sum(old.rms)


def test_paper_assumed_v1_is_the_old_gait_whose_swing_foot_went_through_the_floor():
    """The gait of issue 17: lowest at z = -1.7 cm at t = 0.825 s, below the floor in about a
    quarter of the samples."""
    c = check_gait(PAPER_ASSUMED_V1)
    assert c.lowest_swing_point == pytest.approx(-0.0172, abs=5e-4)
    assert c.lowest_swing_at == pytest.approx(0.825, abs=2e-3)
    t = np.arange(1000) * (PAPER_ASSUMED_V1.T / 1000)
    z = point_mass_positions(exo5(3), gait(exo5(3), t, PAPER_ASSUMED_V1).q)[:, 3, 2, 2]
    assert np.count_nonzero(z < 0) == 249


def test_rounding_the_fitted_parameters_keeps_them():
    assert gait_fit.rounded(GaitParams()) == GaitParams()


# ----------------------------------------------------------------------------- Winter's tables
def _cell(ref: str, value) -> str:
    return f'<c r="{ref}"><v>{value}</v></c>'


def _sheet(rows: dict[int, dict[str, float]]) -> str:
    body = "".join(
        f'<row r="{r}">' + "".join(_cell(f"{c}{r}", v) for c, v in cells.items()) + "</row>"
        for r, cells in sorted(rows.items())
    )
    return (
        '<worksheet xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main"><sheetData>'
        f"{body}</sheetData></worksheet>"
    )


def _workbook(path, sheets: dict[str, dict[int, dict[str, float]]]):
    ns = 'xmlns="http://schemas.openxmlformats.org/spreadsheetml/2006/main"'
    rns = 'xmlns:r="http://schemas.openxmlformats.org/officeDocument/2006/relationships"'
    names = list(sheets)
    wb = (
        f"<workbook {ns} {rns}><sheets>"
        + "".join(f'<sheet name="{n}" sheetId="{k + 1}" r:id="rId{k + 1}"/>' for k, n in enumerate(names))
        + "</sheets></workbook>"
    )
    rels = (
        '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
        + "".join(
            f'<Relationship Id="rId{k + 1}" Target="worksheets/sheet{k + 1}.xml" Type="worksheet"/>'
            for k in range(len(names))
        )
        + "</Relationships>"
    )
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("xl/workbook.xml", wb)
        z.writestr("xl/_rels/workbook.xml.rels", rels)
        for k, n in enumerate(names):
            z.writestr(f"xl/worksheets/sheet{k + 1}.xml", _sheet(sheets[n]))


def test_winters_tables_are_read_from_the_columns_the_module_names(tmp_path):
    """A workbook laid out like the transcription, with known values: the reader finds the stride,
    the speed, the angle curves and the peak loads where the module says they are."""
    frames = range(1, 107)
    dt = 0.0143
    leg = {f: 50.0 + (f % 17) for f in frames}
    thigh = {f: 80.0 + (f % 13) for f in frames}
    a2 = {4 + f: {"B": f, "C": f * dt, "D": 0.5 + 1.4 * f * dt} for f in frames}
    a3 = {4 + f: {"B": f, "C": f * dt, "N": leg[f], "X": thigh[f]} for f in frames}
    # moments: 10 N·m at frame 50 (stance ankle), 5 at 80 (swing hip); force (3, 4) -> 5 N at the knee
    a5 = {
        5 + f: {
            "B": f,
            "C": f * dt,
            "I": 10.0 if f == 50 else 1.0,
            "P": 0.0,
            "X": 5.0 if f == 80 else 0.0,
            "F": 0.0,
            "G": 0.0,
            "M": 3.0 if f == 40 else 0.0,
            "N": 4.0 if f == 40 else 0.0,
            "U": 0.0,
            "V": 0.0,
        }
        for f in frames
    }
    path = tmp_path / "w.xlsx"
    _workbook(path, {"A2.Filtered": a2, "A3.Linear": a3, "A5.Reaction": a5})
    w = winter_appendix(path)
    steps = NEXT_HEEL_CONTACT - HEEL_CONTACT
    assert w.stride_time.value == pytest.approx(round(steps * dt, 3))
    assert w.speed.value == pytest.approx(1.4)
    assert w.theta["leg"] == tuple(leg[f] for f in range(HEEL_CONTACT, NEXT_HEEL_CONTACT + 1))
    assert w.theta["thigh"] == tuple(thigh[f] for f in range(HEEL_CONTACT, NEXT_HEEL_CONTACT + 1))
    assert w.moments["ankle, stance"].value == pytest.approx(round(10.0 / 56.7, 2))
    assert w.moments["hip, swing"].value == pytest.approx(round(5.0 / 56.7, 2))
    assert w.moments["knee, swing"].value == 0.0
    assert w.forces["knee, stance"].value == pytest.approx(round(5.0 / (56.7 * 9.81), 2))
