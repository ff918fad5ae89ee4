"""The command line: inverse dynamics for presets and user files; one-line errors with exit code 2."""

import json

import numpy as np
import pytest
from cli_runs import cli_process

from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.gait.motion import gait, random_states
from exo_bench.models.mechanism.presets import exo5, random_tree


def _states_file(path, q, qd, qdd):
    path.write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
    return path


def test_inverse_exo5_3d_prints_the_backends_tau(tmp_path):
    m = exo5(3)
    mo = gait(m, np.linspace(0, 1.1, 7))
    r = cli_process(
        "inverse", "exo5-3d", _states_file(tmp_path / "s.json", mo.q, mo.qd, mo.qdd), "--method", "pinocchio"
    )
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["method"] == "pinocchio"
    assert np.array_equal(np.array(out["tau"]), pb.inverse_dynamics(m, mo.q, mo.qd, mo.qdd))


def test_inverse_accepts_a_users_own_mechanism_file(tmp_path):
    m = random_tree(4, 3, 5)
    (tmp_path / "mine.json").write_text(m.to_json())
    q, qd, qdd = random_states(m, 3, 1)
    r = cli_process("inverse", tmp_path / "mine.json", _states_file(tmp_path / "s.json", q, qd, qdd))
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["method"] == "matrix-factored"  # the default, as prepare()'s (issue 26)
    from conftest import assert_forces_agree

    assert_forces_agree(
        np.array(out["tau"]),
        pb.inverse_dynamics(m, q, qd, qdd),
        m,
        q,
        qd,
        qdd,
        what="the CLI's default method against Pinocchio",
    )


def test_presets_lists_every_paper_model():
    r = cli_process("presets")
    assert r.returncode == 0
    for key in ("fig1-2d", "fig2a-3d", "fig2b-2d", "fig5-3d", "exo5-3d"):
        assert key in r.stdout


def _bad_cases(tmp_path):
    m = exo5(3)
    q, qd, qdd = random_states(m, 2, 0)
    good = _states_file(tmp_path / "good.json", q, qd, qdd)
    (tmp_path / "broken.json").write_text("{oops")
    bad_mech = m.to_dict()
    bad_mech["links"][2]["n"] = 1.5
    (tmp_path / "badmech.json").write_text(json.dumps(bad_mech))
    short = _states_file(tmp_path / "short.json", q[:, :10], qd, qdd)
    return {
        "unknown method": (["inverse", "exo5-3d", good, "--method", "newton"], "newton"),
        "missing mechanism file": (["inverse", tmp_path / "none.json", good], "no such file"),
        "missing states file": (["inverse", "exo5-3d", tmp_path / "none.json"], "no such file"),
        "invalid JSON states": (["inverse", "exo5-3d", tmp_path / "broken.json"], "invalid JSON"),
        "invalid JSON mechanism": (["inverse", tmp_path / "broken.json", good], "invalid JSON"),
        "invalid mechanism": (["inverse", tmp_path / "badmech.json", good], "link 3 ('swing_thigh'): field 'n'"),
        "wrong state shape": (["inverse", "exo5-3d", short], "(samples, 15)"),
        "unknown command": (["frobnicate"], "invalid choice"),
        "missing argument": (["inverse", "exo5-3d"], "required"),
    }


@pytest.mark.parametrize(
    "case",
    [
        "unknown method",
        "missing mechanism file",
        "missing states file",
        "invalid JSON states",
        "invalid JSON mechanism",
        "invalid mechanism",
        "wrong state shape",
        "unknown command",
        "missing argument",
    ],
)
def test_bad_input_gives_one_line_and_exit_code_2(case, tmp_path):
    args, needle = _bad_cases(tmp_path)[case]
    r = cli_process(*args)
    assert r.returncode == 2
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr and needle in lines[0], lines[0]


def test_nan_from_a_method_is_null_in_json_and_announced(tmp_path):
    """matrix-paper divides 0/0 at sin(phi_i) = 0 (eq. 18 as printed): the output stays valid JSON."""
    m = exo5(3)
    mo = gait(m, np.array([0.0, 0.3]))  # phi_1 = phi_4 = 0 at t = 0
    r = cli_process(
        "inverse", "exo5-3d", _states_file(tmp_path / "s.json", mo.q, mo.qd, mo.qdd), "--method", "matrix-paper"
    )
    assert r.returncode == 0
    tau = json.loads(r.stdout)["tau"]
    assert any(x is None for x in tau[0]) and all(x is not None for x in tau[1])
    assert "NaN/Inf value(s), written as null" in r.stderr and "sample 0" in r.stderr
