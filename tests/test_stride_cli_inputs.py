"""``exo-bench stride`` on a stored stride that was edited or damaged (issue 34's "a stored solution file
edited or truncated", applied to issue 37's stored strides): each is one line on stderr naming the
file, exit 2, never a traceback, an internal error, or a description of numbers the file does not
hold (strings read as numbers, a stride described at a speed other than its file's key).

The stored exo stride at 1.41 m/s is copied to a temporary data folder and edited there; no solve."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from exo_bench.bench.cli.app import main
from exo_bench.bench.studies.stride import data

NAME = "human-2d-exo-v141.npz"


def _edit(z: dict, key: str, value) -> None:
    if key.startswith("meta."):
        meta = json.loads(str(z["meta"]))
        meta[key[5:]] = value
        z["meta"] = np.array(json.dumps(meta))
    else:
        z[key] = value(z[key])


EDITS = {
    "q of strings": ("q", lambda a: a.astype(str)),
    "q of complex numbers": ("q", lambda a: a + 1j),
    "t reversed": ("t", lambda a: a[::-1].copy()),
    "t repeated": ("t", lambda a: np.zeros_like(a)),
    "meta speed of another key": ("meta.speed", 3.0),
    "meta speed a string": ("meta.speed", "fast"),
    "meta variant of another key": ("meta.variant", "human"),
    "meta stride_length a string": ("meta.stride_length", "x"),
    "meta solver a string": ("meta.solver", "x"),
    "meta provenance a string": ("meta.provenance", "x"),
    "meta joint_names a number": ("meta.joint_names", 3),
}


@pytest.fixture
def folder(tmp_path, monkeypatch):
    shutil.copy(data.DATA / NAME, tmp_path / NAME)
    monkeypatch.setattr(data, "DATA", tmp_path)
    return tmp_path


@pytest.mark.case("P8")
@pytest.mark.parametrize("edit", sorted(EDITS))
def test_an_edited_stored_stride_is_one_line_naming_the_file(folder, capsys, edit):
    """A stored stride with arrays of strings or complex numbers (read as numbers: the imaginary part
    dropped), times that do not increase (described as "one stride of 0.0000 s"), a meta whose speed
    or variant is not its file's key (described "at the prescribed 3 m/s" from the v141 file) or whose
    fields have the wrong type (raw "could not convert string to float", an internal AttributeError)
    is one line naming the file, exit 2."""
    path = folder / NAME
    with np.load(path, allow_pickle=False) as f:
        z = dict(f)
    _edit(z, *EDITS[edit])
    with open(path, "wb") as f:
        np.savez(f, **z)
    code = main(["stride", "--variant", "exo", "--speed", "1.41"])
    out, err = capsys.readouterr()
    assert code == 2 and out == "", (out, err)
    assert len(err.strip().splitlines()) == 1 and str(path) in err and "internal error" not in err, err


def test_the_unedited_copy_is_read(folder):
    """The copy itself, unedited, is read from the temporary folder (the refusals above are the edits')."""
    stride = data.load("exo", 1.41)
    assert stride.path == str(folder / NAME) and stride.period > 0.9
