"""Scene files: shipped scenes load; every malformed field is one clear error naming file and field."""

import json

import numpy as np
import pytest

from exo_bench.bench.studies.scenes import load_scene, shipped_scene_names
from exo_bench.models.mechanism.presets import random_tree


def test_every_shipped_scene_loads_and_builds_its_motion():
    names = shipped_scene_names()
    assert {"exo5-3d", "fig2a-2d", "fig2b-2d", "fig5-2d", "exo5-2d"} <= set(names)
    for n in names:
        sc = load_scene(n)
        mo = sc.build_motion()
        assert mo.q.shape[1] == sc.mechanism.dof
        if sc.mechanism.dim == 2:  # a 2D scene has no psi anywhere
            from exo_bench.models.states.states import coordinate_names, force_names

            assert not any("psi" in c for c in coordinate_names(sc.mechanism) + force_names(sc.mechanism))


def _write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


GOOD = """
mechanism = "fig2b-2d"
methods = ["pinocchio"]
[motion]
kind = "planar-gait"
samples_per_period = 50
"""

BAD = {
    "unknown key": (None, 'mechanism = "fig2b-2d"\nmethod = ["x"]\n', "field 'method'"),
    "missing methods": (None, 'mechanism = "fig2b-2d"\n[motion]\nkind = "gait"\n', "field 'methods'"),
    "unknown method": (None, GOOD.replace('["pinocchio"]', '["pinocchio", "euler"]'), "field 'methods'"),
    "unknown output": (None, 'outputs = ["movie"]\n' + GOOD, "field 'outputs'"),
    "reference not run": (None, 'reference = "matrix"\n' + GOOD, "field 'reference'"),
    "bad motion kind": (None, GOOD.replace("planar-gait", "walk"), "field 'motion.kind'"),
    "3D gait on a 2D model": (None, GOOD.replace("planar-gait", "gait"), "field 'motion.kind'"),
    "negative samples": (None, GOOD.replace("50", "-5"), "field 'motion.samples_per_period'"),
    "bad gait override": (None, GOOD + "[motion.gait]\nT = -1.0\n", "field 'motion.gait.T'"),
    "unknown gait parameter": (None, GOOD + "[motion.gait]\nspeed = 2.0\n", "field 'motion.gait.speed'"),
    "unknown named gait": (
        None,
        GOOD + 'gait = "moonwalk"\n',
        "field 'motion.gait': expected a gait among winter-fit-v1, paper-assumed-v1, got 'moonwalk'",
    ),
    "unknown base gait": (None, GOOD + "[motion.gait]\nbase = 3\n", "field 'motion.gait.base'"),
    "unknown preset": (None, GOOD.replace("fig2b-2d", "fig9-2d"), "field 'mechanism'"),
    "invalid TOML": (None, "mechanism = [", "invalid TOML"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_malformed_scene_names_file_and_field(case, tmp_path):
    _, text, needle = BAD[case]
    p = _write(tmp_path, text)
    with pytest.raises(ValueError) as e:
        load_scene(p)
    msg = str(e.value)
    assert msg.startswith(str(p)) and needle in msg, msg


def test_a_scene_selects_a_named_gait_and_overrides_its_fields(tmp_path):
    from exo_bench.models.gait.motion import GAITS, PAPER_ASSUMED_V1, GaitParams, planar_gait

    default = load_scene(_write(tmp_path, GOOD, "a.toml"))
    assert default.motion["params"] == GaitParams() and "winter-fit-v1" in default.motion_label()
    old = load_scene(_write(tmp_path, GOOD + 'gait = "paper-assumed-v1"\n', "b.toml"))
    assert old.motion["params"] == PAPER_ASSUMED_V1 == GAITS["paper-assumed-v1"]
    assert "paper-assumed-v1" in old.motion_label()
    mo = old.build_motion()  # the old figures' motion, sample for sample
    np.testing.assert_array_equal(mo.q, planar_gait(old.mechanism, mo.t, PAPER_ASSUMED_V1).q)
    assert mo.t[-1] == pytest.approx(1.1 * 49 / 50)
    changed = load_scene(_write(tmp_path, GOOD + '[motion.gait]\nbase = "paper-assumed-v1"\nT = 2.0\n', "c.toml"))
    assert changed.motion["params"].T == 2.0 and changed.motion["params"].j == PAPER_ASSUMED_V1.j
    assert "paper-assumed-v1 with T changed" in changed.motion_label()


def test_invalid_mechanism_file_in_a_scene_names_the_link(tmp_path):
    d = random_tree(3, 3, 0).to_dict()
    d["links"][1]["masses"] = [1.0, -2.0, 1.0]
    (tmp_path / "m.json").write_text(json.dumps(d))
    p = _write(tmp_path, 'mechanism = "m.json"\nmethods = ["pinocchio"]\n[motion]\nkind = "smooth-random"\n')
    with pytest.raises(ValueError, match=r"field 'mechanism': .*m.json: link 2 .*'masses\[1\]'.*-2.0"):
        load_scene(p)


def test_unknown_scene_is_a_clear_error():
    with pytest.raises(ValueError, match="not a shipped scene .* and no such file"):
        load_scene("no-such-scene")


def test_states_file_motion_is_validated(tmp_path):
    (tmp_path / "st.json").write_text(
        json.dumps(
            {
                "t": [0, 1],
                "q": [[0.1, 0.2, 1.0, 1.0]] * 2,
                "qd": [[0, 0, 0, 0]] * 2,
                "qdd": [[0, 0, 0, float("nan")]] * 2,
            }
        )
    )
    p = _write(
        tmp_path, 'mechanism = "fig2a-2d"\nmethods = ["pinocchio"]\n[motion]\nkind = "states"\nfile = "st.json"\n'
    )
    with pytest.raises(ValueError, match=r"motion.file 'st.json'.*'qdd' sample 0 coordinate l2"):
        load_scene(p)
