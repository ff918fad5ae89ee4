"""A states file is judged before it is read, and what is judged is what is loaded (issue 34: L1, L2)."""

import contextlib
import io
import json
import zipfile

import numpy as np
import pytest
from cli_runs import run_cli
from conftest import K, assert_forces_agree

from exo_bench.bench.cli import inverse as inverse_cli
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5

MECH = exo5(3)


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, a, allow_pickle=False)
    return buf.getvalue()


def _archive(path, members: list[tuple[str, np.ndarray]]):
    with zipfile.ZipFile(path, "w") as zf:
        for name, a in members:
            with pytest.warns(UserWarning) if name in zf.namelist() else contextlib.nullcontext():
                zf.writestr(name, _npy(a))
    return path


@pytest.mark.case("L1")
@pytest.mark.parametrize("command", ["inverse", "forward"])
@pytest.mark.parametrize("shadow", ["q", "q.npy"], ids=["q-beside-q.npy", "q.npy-twice"])
def test_two_members_one_key_can_name_are_refused_before_reading(tmp_path, command, shadow):
    """An .npz with two members that one key can name (``q`` beside ``q.npy``, or ``q.npy`` twice) is refused
    in one line naming the key, before any array is inflated: the header checked and the array numpy loads
    could be different members."""
    q, qd, qdd = random_states(MECH, 2, 0)
    third = "tau" if command == "forward" else "qdd"
    big = np.zeros((200_000, MECH.dof))  # 24 MB: judged by the small one's header, loaded as this one
    path = _archive(tmp_path / "s.npz", [("q.npy", q), ("qd.npy", qd), (f"{third}.npy", qdd), (shadow, big)])
    loaded = []
    real = inverse_cli._load_states
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(inverse_cli, "_load_states", lambda *a, **k: loaded.append(a) or real(*a, **k))
        if command == "forward":
            mp.setattr("exo_bench.bench.cli.forward._load_states", inverse_cli._load_states)
        rc, out, err = run_cli([command, "exo5-3d", path, "--max-memory", "300M"])
    assert rc == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "two members named 'q'" in err
    assert not loaded


@pytest.mark.case("L2")
@pytest.mark.parametrize("kind", ["json", "npz"])
def test_forward_checks_its_limits_before_reading_the_states(tmp_path, kind):
    """``forward`` refuses a states file over ``--max-time`` from its size (JSON) or its headers (.npz),
    before reading it, as ``inverse`` does; the reading is counted, not timed."""
    q, qd, qdd = random_states(MECH, 40_000, 0)
    if kind == "json":
        path = tmp_path / "s.json"
        path.write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "tau": qdd.tolist()}))
    else:
        path = tmp_path / "s.npz"
        np.savez(path, q=q, qd=qd, tau=qdd)
    loaded = []
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr("exo_bench.bench.cli.forward._load_states", lambda *a, **k: loaded.append(a) or pytest.fail("read"))
        rc, out, err = run_cli(["forward", "exo5-3d", path, "--max-time", "0.01"])
    assert rc == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert "--max-time" in err or "max-time" in err or "seconds" in err, err
    assert not loaded


def test_a_well_formed_archive_is_still_read_by_forward(tmp_path):
    """Not a refusal by accident: an .npz of q, qd, tau within the limits gives accelerations."""
    q, qd, qdd = random_states(MECH, 3, 1)
    path = tmp_path / "s.npz"
    from exo_bench import prepare

    tau = prepare(MECH, "newton-euler").inverse_dynamics(q, qd, qdd)
    np.savez(path, q=q, qd=qd, tau=tau)
    rc, out, err = run_cli(["forward", "exo5-3d", path])
    assert rc == 0, err
    got = np.array(json.loads(out)["qdd"])
    model = prepare(MECH, "pinocchio")  # the answer's backward error, in the error model
    assert_forces_agree(model.inverse_dynamics(q, qd, got), tau, MECH, q, qd, got, k=4 * K)
