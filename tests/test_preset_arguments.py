"""The presets' arguments are checked before they name the mechanism (models/mechanism/presets.py): ``human(True)``
said "human-Trued: field 'dim': expected 2 or 3, got True", a name made from the bad value, and
``human(2.0)`` made a mechanism named "human-2.0d". A bool, a float or a string where a whole number is
expected is refused in one ValueError naming the preset, the field and the expected type."""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.models.mechanism import presets

BAD_WHOLE = [True, False, 2.0, 3.0, "2", None, 2.5, np.float64(3.0)]
BUILDERS = {
    "human": lambda v: presets.human(dim=v),
    "fig1": lambda v: presets.fig1(v),
    "fig2a": lambda v: presets.fig2a(v),
    "fig2b": lambda v: presets.fig2b(v),
    "fig5": lambda v: presets.fig5(v),
    "exo5": lambda v: presets.exo5(v),
    "chain": lambda v: presets.chain(3, v),
    "chain-seeded": lambda v: presets.chain(3, v, seed=1),
    "random_tree": lambda v: presets.random_tree(3, v, 1),
}


@pytest.mark.parametrize("value", BAD_WHOLE, ids=repr)
@pytest.mark.parametrize("preset", list(BUILDERS))
def test_a_dim_that_is_not_a_whole_number_is_refused_naming_the_field_and_type(preset, value):
    with pytest.raises(ValueError) as e:
        BUILDERS[preset](value)
    msg = str(e.value)
    assert "field 'dim'" in msg and "an integer" in msg and repr(value) in msg, msg
    assert f"-{value}d" not in msg and "\n" not in msg, msg  # never a name made of the bad value


@pytest.mark.parametrize(
    "call, field",
    [
        (lambda: presets.chain(True), "nlinks"),
        (lambda: presets.chain(2.0), "nlinks"),
        (lambda: presets.chain("3"), "nlinks"),
        (lambda: presets.random_tree(True, 2, 1), "nlinks"),
        (lambda: presets.chain(3, 2, seed=True), "seed"),
        (lambda: presets.chain(3, 2, seed=1.5), "seed"),
        (lambda: presets.random_tree(3, 2, "1"), "seed"),
    ],
)
def test_nlinks_and_seed_must_be_integers(call, field):
    with pytest.raises(ValueError, match=rf"field '{field}': expected an integer"):
        call()


def test_integers_of_numpy_are_whole_numbers():
    assert presets.human(np.int64(3)).name == "human-3d"
    assert presets.chain(np.int32(4), np.int64(2), seed=np.int64(7)).name == "chain4-2d-seed7"
    assert presets.random_tree(3, 3, 0).dim == 3
