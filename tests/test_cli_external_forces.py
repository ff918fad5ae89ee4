"""``exo-bench inverse`` and ``forward`` read ``f_ext`` from the states file (issue 37): an optional array
``(samples, links, 3, dim)`` beside ``q, qd, qdd`` (or ``tau``), in JSON or ``.npz``; the CLI's numbers are
the API's with ``f_ext`` to the last bit, and a bad ``f_ext`` is one line and exit 2."""

from __future__ import annotations

import json

import numpy as np
from cli_runs import cli_process
from test_external_forces import _case

from exo_bench import prepare
from exo_bench.models.mechanism.presets import exo5

MECH = exo5(2)


def test_inverse_and_forward_take_f_ext(tmp_path):
    q, qd, qdd, f = _case(MECH, 3, 2)
    model = prepare(MECH, "newton-euler")
    tau = model.inverse_dynamics(q, qd, qdd, f_ext=f)
    path = tmp_path / "s.json"
    path.write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist(), "f_ext": f.tolist()}))
    r = cli_process("inverse", "exo5-2d", path, "--method", "newton-euler")
    assert r.returncode == 0, r.stderr
    assert np.array_equal(np.array(json.loads(r.stdout)["tau"]), tau)
    npz = tmp_path / "s.npz"
    np.savez(npz, q=q, qd=qd, tau=tau, f_ext=f)
    r = cli_process("forward", "exo5-2d", npz, "--method", "newton-euler")
    assert r.returncode == 0, r.stderr
    assert np.array_equal(np.array(json.loads(r.stdout)["qdd"]), model.forward_dynamics(q, qd, tau, f_ext=f))


def test_a_bad_f_ext_is_one_line(tmp_path):
    q, qd, qdd, f = _case(MECH, 3, 2)
    f[1, 4, 2, 0] = np.inf
    path = tmp_path / "s.npz"
    np.savez(path, q=q, qd=qd, qdd=qdd, f_ext=f)
    r = cli_process("inverse", "exo5-2d", path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert f"sample 1, link 5 ({MECH.names[4]!r}), point 'end', component x" in r.stderr
    np.savez(path, q=q, qd=qd, qdd=qdd, f_ext=f[:, :3])
    r = cli_process("inverse", "exo5-2d", path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "field 'f_ext'" in r.stderr and "(2, 3, 3, 2)" in r.stderr
    bad = tmp_path / "b.json"
    bad.write_text(
        json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist(), "f_ext": [[[["x"] * 2] * 3] * 5] * 2})
    )
    r = cli_process("inverse", "exo5-2d", bad)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "field 'f_ext': expected forces in newtons (numbers)" in r.stderr
