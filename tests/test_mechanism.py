"""The mechanism as data: JSON round trips and one clear error per class of bad input."""

import json
import math

import numpy as np
import pytest

from exo_bench.models.mechanism.presets import load_mechanism, save_mechanism
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states, coordinate_names
from exo_bench.models.mechanism.presets import PRESETS, exo5, random_tree

ISSUE_EXAMPLE = {
    "dim": 3,
    "g": 9.81,
    "links": [
        {"parent": -1, "sign": 1, "masses": [0.7275, 1.455, 0.7275], "n": 0.595},
        {"parent": 0, "sign": 1, "masses": [2.2325, 4.465, 2.2325], "n": 0.545},
    ],
}


def test_documented_json_format_loads():
    m = Mechanism.from_dict(ISSUE_EXAMPLE)
    assert (m.dim, m.nlinks, m.dof, m.parent) == (3, 2, 6, (-1, 0))
    assert math.isclose(m.total_mass, 2.91 + 8.93)


@pytest.mark.parametrize("key", sorted(PRESETS))
def test_json_round_trip_preserves_every_field(key, tmp_path):
    m = PRESETS[key]()
    save_mechanism(m, tmp_path / "m.json")
    assert load_mechanism(tmp_path / "m.json") == m


def test_random_trees_have_parents_before_children_and_random_signs():
    trees = [random_tree(8, 3, s) for s in range(20)]
    assert all(all(p < i for i, p in enumerate(t.parent)) for t in trees)
    assert {s for t in trees for s in t.sign} == {-1, 1}
    assert any(t.parent.count(-1) > 1 for t in trees)  # forests hang from O too


def test_exo5_is_the_papers_tree_with_its_masses():
    m = exo5(3)
    assert m.parent == (-1, 0, 1, 2, 1) and m.sign == (1, 1, -1, -1, 1)
    assert np.allclose(m.mass_array.sum(1), [2.91, 8.93, 8.93, 2.91, 28.93])
    assert np.allclose(m.mass_array[:, 1] / m.mass_array.sum(1), 0.5)
    assert m.n == (0.595, 0.545, 0.545, 0.595, 0.5)


def test_coordinates_are_in_block_order():
    assert coordinate_names(exo5(3))[:2] + coordinate_names(exo5(3))[5:6] + coordinate_names(exo5(3))[-1:] == [
        "phi1",
        "phi2",
        "psi1",
        "l5",
    ]
    assert "psi1" not in coordinate_names(exo5(2))


def _bad(mutate):
    d = json.loads(json.dumps(ISSUE_EXAMPLE))
    mutate(d)
    return d


BAD = {
    "negative mass": (lambda d: d["links"][1]["masses"].__setitem__(0, -1.0), ["link 2", "masses[0]", ">= 0", "-1.0"]),
    "nan mass": (lambda d: d["links"][0]["masses"].__setitem__(2, float("nan")), ["link 1", "masses[2]", "nan"]),
    "infinite mass": (lambda d: d["links"][0]["masses"].__setitem__(1, float("inf")), ["link 1", "masses[1]", "inf"]),
    "fraction above 1": (lambda d: d["links"][1].__setitem__("n", 1.5), ["link 2", "'n'", "(0, 1)", "1.5"]),
    "fraction 0": (lambda d: d["links"][0].__setitem__("n", 0.0), ["link 1", "'n'", "(0, 1)", "0.0"]),
    "parent not earlier": (lambda d: d["links"][1].__setitem__("parent", 1), ["link 2", "'parent'", "earlier", "1"]),
    "parent below -1": (lambda d: d["links"][0].__setitem__("parent", -2), ["link 1", "'parent'", "-2"]),
    "sign 0": (lambda d: d["links"][1].__setitem__("sign", 0), ["link 2", "'sign'", "+1 or -1", "0"]),
    "dim 4": (lambda d: d.__setitem__("dim", 4), ["'dim'", "2 or 3", "4"]),
    "no links": (lambda d: d.__setitem__("links", []), ["'links'", "non-empty", "[]"]),
    "all-zero masses": (
        lambda d: [lk.__setitem__("masses", [0, 0, 0]) for lk in d["links"]],
        ["'masses'", "positive", "all zero"],
    ),
    "mass is a string": (
        lambda d: d["links"][0].__setitem__("masses", ["1", 1, 1]),
        ["link 1", "'masses'", "three numbers", "'1'"],
    ),
    "two masses": (
        lambda d: d["links"][0].__setitem__("masses", [1, 1]),
        ["link 1", "'masses'", "three numbers", "[1, 1]"],
    ),
    "sign is bool": (lambda d: d["links"][0].__setitem__("sign", True), ["link 1", "'sign'", "True"]),
    "parent is float": (lambda d: d["links"][1].__setitem__("parent", 0.0), ["link 2", "'parent'", "0.0"]),
    "g is a string": (lambda d: d.__setitem__("g", "9.81"), ["'g'", "finite number", "'9.81'"]),
    "missing key n": (lambda d: d["links"][1].pop("n"), ["link 2", "missing", "'n'"]),
    "missing key links": (lambda d: d.pop("links"), ["missing", "'links'"]),
    "unknown key": (lambda d: d["links"][0].__setitem__("mass", 1), ["link 1", "unknown", "'mass'"]),
    "link not an object": (lambda d: d["links"].__setitem__(0, 3), ["link 1", "expected an object", "3"]),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_names_link_field_expected_and_actual(case):
    mutate, needles = BAD[case]
    with pytest.raises(ValueError) as e:
        Mechanism.from_dict(_bad(mutate), source="m.json")
    msg = str(e.value)
    assert msg.startswith("m.json"), msg
    for needle in needles:
        assert needle in msg, (needle, msg)


def test_link_name_appears_in_messages():
    d = _bad(lambda d: d["links"][1].update(name="thigh", n=2.0))
    with pytest.raises(ValueError, match=r"link 2 \('thigh'\): field 'n'"):
        Mechanism.from_dict(d)


def test_direct_construction_is_validated_too():
    with pytest.raises(ValueError, match=r"link 1 .*'n'.*got 1.0"):
        Mechanism(dim=2, g=9.81, parent=(-1,), sign=(1,), masses=((1, 1, 1),), n=(1.0,))


def test_state_arrays_are_validated_at_the_edge():
    m = exo5(3)
    q = np.ones((2, 15))
    with pytest.raises(ValueError, match=r"'q'.*\(samples, 15\).*\(2, 14\)"):
        as_states(m, np.ones((2, 14)), q, q)
    bad = q.copy()
    bad[1, 3] = np.nan
    with pytest.raises(ValueError, match=r"'qd' sample 1 coordinate phi4.*nan"):
        as_states(m, q, bad, q)
    neg = q.copy()
    neg[0, 12] = -0.1
    with pytest.raises(ValueError, match=r"sample 0 coordinate l3 .*swing_thigh.*>= 0.*-0.1"):
        as_states(m, neg, q, q)
    with pytest.raises(ValueError, match="same number of samples"):
        as_states(m, q, q[:1], q)


def test_unknown_preset_or_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(ValueError, match="not a preset .* and no such file"):
        load_mechanism(tmp_path / "nope.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(ValueError, match="invalid JSON"):
        load_mechanism(tmp_path / "bad.json")


def _one_link(**changes):
    d = dict(dim=2, g=9.81, parent=(-1,), sign=(1,), masses=((0.1, 0.2, 0.3),), n=(0.5,), name="m")
    d.update(changes)
    return Mechanism(**d)


@pytest.mark.parametrize(
    "changes,message",
    [
        ({"dim": 5}, r"m: field 'dim': expected 2 or 3, got 5"),
        ({"dim": True}, r"m: field 'dim': expected 2 or 3, got True"),
        ({"g": float("nan")}, r"m: field 'g': expected a finite number, got nan"),
        ({"g": 10**400}, r"m: field 'g': expected a finite number, got 1000"),  # an int no float can hold
        ({"masses": ((0.1, 10**400, 0.3),)}, r"link 1 \('link1'\): field 'masses\[1\]': expected a finite mass >= 0"),
        ({"n": (10**400,)}, r"link 1 \('link1'\): field 'n': expected a fraction in \(0, 1\)"),
    ],
)
def test_the_constructor_validates_every_field_itself(changes, message):
    """Mechanism(...) directly (not through JSON) names the field, the expected and the actual value."""
    with pytest.raises(ValueError, match=message):
        _one_link(**changes)


@pytest.mark.parametrize(
    "field,value,message",
    [
        ("dim", 2.0, r"field 'dim': expected 2 or 3, got 2.0"),
        ("parent", 0.5, r"link 1: field 'parent': expected an integer index of an earlier link or -1, got 0.5"),
        ("parent", True, r"link 1: field 'parent': expected an integer index of an earlier link or -1, got True"),
        ("sign", 1.0, r"link 1: field 'sign': expected \+1 or -1, got 1.0"),
        ("sign", True, r"link 1: field 'sign': expected \+1 or -1, got True"),
    ],
)
def test_json_numbers_of_the_wrong_type_are_refused(field, value, message):
    """JSON 2.0, 1.0 or true where an integer belongs is refused, not silently converted."""
    data = json.loads(json.dumps(ISSUE_EXAMPLE))
    if field == "dim":
        data["dim"] = value
    else:
        data["links"][0][field] = value
    with pytest.raises(ValueError, match=message):
        Mechanism.from_dict(data, source="file.json")


def test_negative_zero_gravity_is_stored_as_zero():
    """g = -0.0 is accepted (it is not negative) and stored as +0.0: one mechanism, one JSON."""
    m = _one_link(g=-0.0)
    assert math.copysign(1.0, m.g) == 1.0 and '"g": 0.0' in m.to_json()
    assert m == _one_link(g=0.0) and m.to_json() == _one_link(g=0.0).to_json()
