"""The gait demo writes every scene's figures and recordings, and keeps going past a failing method."""

from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from bench.gait_demo import SCENES, gait_study, main, write_gait_outputs
from bench.recording import rerun_executable, verify_recording


def _meta(path) -> dict:
    """The static components of the recording's ``meta`` entity, merged over its chunks."""
    out = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.entity_path == "/meta":
            rb = chunk.to_record_batch()
            for n in rb.schema.names:
                vals = [v for v in rb.column(n).to_pylist() if v is not None]
                if n != "rerun.controls.RowId" and vals:
                    out[n] = vals[-1]
    assert out, "no meta entity"
    return out


def test_every_scene_gets_its_figures_and_a_verified_recording(tmp_path):
    paths = write_gait_outputs(tmp_path, methods=("pinocchio", "no-such-method"), samples=40)
    names = {p.name for p in paths}
    for scene in ("exo5-3d", "fig2a-2d", "fig2b-2d", "fig5-2d"):
        assert {f"{scene}-moments.png", f"{scene}-forces.png", f"{scene}-kinogram.png", f"{scene}.rrd"} <= names
    assert "exo5-3d-overview.png" in names
    assert not any(n.endswith("-differences.png") for n in names)     # only one method succeeded
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(names)   # nothing else, no temporary files
    meta = _meta(tmp_path / "exo5-3d.rrd")
    assert meta["methods"] == ["pinocchio", "no-such-method"] and meta["methods_ok"] == ["pinocchio"]
    assert "no-such-method: failed (ValueError: method: expected one of" in meta["TextDocument:text"][0]
    if rerun_executable() is not None:
        for p in paths:
            if p.suffix == ".rrd":
                verify_recording(p)


def test_the_exoskeleton_follows_eq_26_and_the_planar_scenes_its_sagittal_version():
    exo, *planar = [gait_study(s, ["pinocchio"], samples=20) for s in SCENES]
    assert exo.mechanism.dim == 3 and exo.mechanism.nlinks == 5 and "eq. (26)" in exo.motion_label
    assert [s.mechanism.name for s in planar] == ["fig2a-2d", "fig2b-2d", "fig5-2d"]
    for s in (exo, *planar):
        assert s.motion.t.shape == (20,) and np.isclose(s.motion.t[1] * 20, 1.1)   # one period T = 1.1 s


def test_bad_arguments_are_refused_with_a_clear_message(capsys):
    with pytest.raises(ValueError, match="samples"):
        gait_study(SCENES[0], ["pinocchio"], samples=1)
    with pytest.raises(ValueError, match="methods"):
        gait_study(SCENES[0], [], samples=10)
    assert main(["/tmp/unused", "--samples", "1"]) == 2
    assert "gait_demo: gait scenes: field 'samples'" in capsys.readouterr().err
