"""``exo-bench states PRESET -o FILE`` (issue 38): example states for every preset, in the format
``inverse`` and ``forward`` read, written through the one safe writer (bench/output/files.py).

Error model of the round trip: the file's ``tau`` is the default method's inverse dynamics of its
``q, qd, qdd``; ``inverse`` on the file recomputes it with method newton-euler, an independent
implementation, so the two agree within the agreement bound of tests/conftest.py (``K`` ulps of
the term scale). ``forward`` solves ``M qdd = tau - b``: its error is the forces' error amplified by
the condition number of ``M``, so ``|qdd - qdd_file| <= K eps cond(M) (|qdd| + |M^-1| |term scale|)``,
bounded here by ``K eps cond(M) * (max |qdd| + max term scale * |M^-1|)`` per sample.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from cli_runs import run_cli
from exo_bench.models.mechanism.presets import PRESETS

from conftest import EPS, K, assert_forces_agree, term_scale


@pytest.mark.parametrize("preset", sorted(PRESETS))
def test_states_of_every_preset_run_through_inverse_and_forward(preset, tmp_path):
    from exo_bench.api import prepare
    from exo_bench.models.mechanism.presets import load_mechanism

    path = tmp_path / "s.json"
    code, _, err = run_cli(["states", preset, "-o", path, "--samples", "3", "--seed", "7"])
    assert code == 0, err
    data = json.loads(path.read_text())
    mech = load_mechanism(preset)
    q, qd, qdd, tau = (np.asarray(data[k], dtype=float) for k in ("q", "qd", "qdd", "tau"))
    for a in (q, qd, qdd, tau):
        assert a.shape == (3, mech.dof)
    prepare(mech, "newton-euler").check_regular(q)  # away from singular and ill-conditioned M
    code, out, err = run_cli(["inverse", preset, path, "--method", "newton-euler"])
    assert code == 0, err
    assert_forces_agree(np.asarray(json.loads(out)["tau"]), tau, mech, q, qd, qdd, what=f"{preset} states' tau")
    code, out, err = run_cli(["forward", preset, path])
    assert code == 0, err
    got = np.asarray(json.loads(out)["qdd"])
    model = prepare(mech, "newton-euler")
    for s in range(q.shape[0]):
        m = model.mass_matrix(q[s : s + 1])[0]
        bound = (
            K
            * EPS
            * np.linalg.cond(m)
            * (np.abs(qdd[s]).max() + np.abs(np.linalg.inv(m)).max() * term_scale(mech, q, qd, qdd)[s].max())
        )
        assert np.abs(got[s] - qdd[s]).max() <= bound, (preset, s)


def test_states_npz_and_the_same_seed_gives_the_same_file(tmp_path):
    a, b = tmp_path / "a.npz", tmp_path / "b.npz"
    for p in (a, b):
        code, _, err = run_cli(["states", "exo5-3d", "-o", p, "--samples", "4", "--seed", "1"])
        assert code == 0, err
    with np.load(a) as x, np.load(b) as y:
        assert set(x.files) == {"q", "qd", "qdd", "tau"}
        for k in x.files:
            assert x[k].shape == (4, 15) and np.array_equal(x[k], y[k])
    code, out, err = run_cli(["inverse", "exo5-3d", a])
    assert code == 0, err
    assert np.asarray(json.loads(out)["tau"]).shape == (4, 15)


def test_states_never_writes_through_a_link_nor_leaves_a_temporary(tmp_path):
    target = tmp_path / "precious.json"
    target.write_text("keep")
    link = tmp_path / "s.json"
    os.symlink(target, link)
    code, _, err = run_cli(["states", "exo5-2d", "-o", link])
    assert code == 2 and "symlink" in err and len(err.strip().splitlines()) == 1
    assert target.read_text() == "keep"
    code, _, err = run_cli(["states", "no-such-preset", "-o", tmp_path / "x.json"])
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["precious.json", "s.json"]  # nothing half-written


@pytest.mark.parametrize("argv", [["--samples", "0"], ["--samples", "x"], ["--seed", "-1"], ["--samples", str(10**15)]])
def test_states_bad_counts_are_one_line(argv, tmp_path):
    code, _, err = run_cli(["states", "exo5-2d", "-o", tmp_path / "s.json", *argv])
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s.json").exists()
