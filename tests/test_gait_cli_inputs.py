"""``exo-bench gait`` on a stored step whose arrays were edited to strings or complex numbers (issue 34's
"a stored solution file edited", applied to the stored steps, read like the strides by
:func:`exo_bench.bench.studies.step.data.read_stored`): one line naming the file and the field,
exit 2, never the numbers parsed from the strings. The stored exo5-2d step is copied to a
temporary data folder and edited there; no solve."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from exo_bench.bench.cli.app import main
from exo_bench.bench.studies.step import data

NAME = "exo5-2d-step.npz"


@pytest.mark.case("P8")
@pytest.mark.parametrize("dtype", [str, complex])
def test_a_stored_step_of_strings_or_complex_numbers_is_refused(tmp_path, monkeypatch, capsys, dtype):
    """A stored step whose q holds strings ("0.3") or complex numbers was read as numbers (np.ascontiguousarray
    with dtype=float parsed the strings and dropped the imaginary parts): the file and field are named, exit 2."""
    path = tmp_path / NAME
    shutil.copy(data.DATA / NAME, path)
    monkeypatch.setattr(data, "DATA", tmp_path)
    with np.load(path, allow_pickle=False) as f:
        z = dict(f)
    z["q"] = z["q"].astype(dtype)
    with open(path, "wb") as f:
        np.savez(f, **z)
    code = main(["gait", "--dim", "2"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "", (out, err)
    assert str(path) in err and "field 'q'" in err and len(err.strip().splitlines()) == 1, err
