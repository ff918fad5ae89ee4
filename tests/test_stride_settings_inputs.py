"""The stride problem's settings refuse bad values where they are made (bench/studies/stride/problem.py
``StrideSettings``, data.py ``check_settings``): ``passive`` (a model of passive.PASSIVE), ``spring``
(three linear joint springs, N·m/kg/rad, each finite and >= 0), ``w_floor`` (the floor-work price, finite
and >= 0) and ``contact`` (fields of models.contact.ContactParameters, with its values' checks).

Each refusal is a ValueError naming the field (and the joint of a spring), what was expected and what
was given; before, a bad ``passive`` was refused only when the objective was built and the others not
at all (a NaN spring or floor price reached IPOPT, a negative one rewarded what it should price). A stored
stride whose settings were edited so is refused when it is read: ``exo-bench stride`` prints one line
naming the file and the field and exits 2.

Cheap: settings are built without a mechanism; the CLI reads a copy of one stored stride, no solve.
"""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from exo_bench.bench.cli.app import main
from exo_bench.bench.studies.stride import data
from exo_bench.bench.studies.stride.problem import StrideSettings, settings_from

NAN, INF = math.nan, math.inf

#: field -> [(bad value, what the message must name besides the field)]
BAD = {
    "passive": [("hill", "'hill'"), ("Anderson-Pandy", "'Anderson-Pandy'"), (1, "1"), (True, "True"), (None, "None")],
    "spring": [
        ((0.0, 0.0, NAN), "ankle"),
        ((INF, 0.0, 0.0), "hip"),
        ((0.0, -1.0, 0.0), "knee"),
        ((0.0, 0.0, "0.25"), "ankle"),
        ((True, 0.0, 0.0), "hip"),
        ((0.0, 0.0), "(0.0, 0.0)"),
        ("stiff", "'stiff'"),
        (0.25, "0.25"),
    ],
    "w_floor": [(NAN, "nan"), (INF, "inf"), (-1.0, "-1.0"), ("5", "'5'"), (True, "True"), (None, "None")],
    "contact": [
        ({"heel": 1.0}, "'heel'"),
        ({"stiffness": NAN}, "stiffness"),
        ({"stiffness": INF}, "stiffness"),
        ({"dissipation": -1.0}, "dissipation"),
        ({"radius": "0.03"}, "radius"),
        ({"static_friction": True}, "static_friction"),
        ("soft", "'soft'"),
    ],
}
CASES = [(f, v, named) for f, bad in BAD.items() for v, named in bad]


@pytest.mark.parametrize("field, value, named", CASES, ids=[f"{f}={v!r}" for f, v, _ in CASES])
def test_a_bad_setting_is_refused_where_the_settings_are_made(field, value, named):
    """``StrideSettings(field=bad)``: a one-line ValueError naming the field, the expectation and the value."""
    with pytest.raises(ValueError) as e:
        StrideSettings(**{field: value})
    msg = str(e.value)
    assert "\n" not in msg and f"field '{field}" in msg and "expected" in msg and named in msg, msg


@pytest.mark.parametrize("field, value, named", CASES[::4], ids=[f"{f}={v!r}" for f, v, _ in CASES[::4]])
def test_a_bad_stored_setting_is_refused_by_settings_from(field, value, named):
    """The settings read back from a stored stride (JSON: lists) are checked as the constructor's."""
    stored = StrideSettings().to_dict()
    stored[field] = list(value) if isinstance(value, tuple) else value
    with pytest.raises(ValueError, match=f"field '{field}"):
        settings_from(stored)


def test_good_settings_are_kept_as_given():
    """Zero springs and price, the other passive model, contact fields at their bounds: accepted, unchanged."""
    s = StrideSettings(passive="anderson-pandy", spring=(0, 0.0, 3), w_floor=0, contact={"dissipation": 0.0})
    assert (s.passive, s.spring, s.w_floor, s.contact) == ("anderson-pandy", (0, 0.0, 3), 0, {"dissipation": 0.0})
    assert data.contact_of(s).dissipation == 0.0


def test_every_stored_stride_and_trial_has_valid_settings_read_back_unchanged():
    """The stored strides and trials (data/, data/trials/) pass the checks, and their settings come back
    as stored (no number of the stored problems changes)."""
    paths = sorted(data.DATA.glob("**/*.npz"))
    assert len(paths) >= 4
    for p in paths:
        with np.load(p, allow_pickle=False) as f:
            stored = json.loads(str(f["meta"]))["settings"]
        back = json.loads(json.dumps(settings_from(stored).to_dict()))
        assert {k: back[k] for k in stored} == stored, p


NAME = "human-2d-exo-v141.npz"
EDITS = {
    "passive unknown": ("passive", "hill"),
    "spring negative": ("spring", [0.0, 0.0, -0.25]),
    "spring a string": ("spring", "stiff"),
    "w_floor a string": ("w_floor", "5"),
    "w_floor negative": ("w_floor", -5.0),
    "contact unknown field": ("contact", {"heel": 1.0}),
    "contact stiffness negative": ("contact", {"stiffness": -1.0}),
}


@pytest.fixture
def edited(tmp_path, monkeypatch):
    """``edit(key, value)``: the stored exo stride at 1.41 m/s, copied to a temporary data folder, with
    ``meta.settings[key] = value``; returns the copy's path."""
    source = data.DATA / NAME
    monkeypatch.setattr(data, "DATA", tmp_path)

    def edit(key, value):
        path = tmp_path / NAME
        shutil.copy(source, path)
        with np.load(path, allow_pickle=False) as f:
            z = dict(f)
        meta = json.loads(str(z["meta"]))
        meta["settings"][key] = value
        z["meta"] = np.array(json.dumps(meta))
        with open(path, "wb") as f:
            np.savez(f, **z)
        return path

    return edit


@pytest.mark.parametrize("edit", sorted(EDITS))
def test_the_cli_on_a_stored_stride_with_bad_settings_is_one_line(edited, capsys, edit):
    """``exo-bench stride`` on a stored stride whose settings were edited: one line on stderr naming the
    file and the field, exit 2 (before, the passive, spring and floor price were described as if valid
    and a bad contact was a line naming neither the file nor the stride's field)."""
    key, value = EDITS[edit]
    path = edited(key, value)
    code = main(["stride", "--variant", "exo", "--speed", "1.41"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "", (out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and str(path) in err and f"meta.settings.{key}" in err, err
    assert "internal error" not in err and "Traceback" not in err, err


def test_the_cli_solve_on_a_stored_stride_with_bad_settings_is_one_line_before_solving(edited, capsys):
    """``exo-bench stride --solve`` reads the stored settings first: a bad one is one line, exit 2, no solve."""
    pytest.importorskip("casadi")
    path = edited("spring", [0.0, 0.0, float("nan")])
    code = main(["stride", "--solve", "--variant", "exo", "--speed", "1.41"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "", (out, err)
    assert len(err.strip().splitlines()) == 1 and str(path) in err and "meta.settings.spring" in err, err
