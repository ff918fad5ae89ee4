"""Numeric Lagrange II against the Pinocchio backend on seeded random trees, power balance along
smooth motions, and the command line."""

import json

import numpy as np
import pytest
from conftest import POWER_BALANCE_TOL, assert_forces_agree, assert_mass_matrices_agree, power_balance_residual

from exo_bench import prepare
from exo_bench.bench.cli import main
from exo_bench.lagrange import numeric as ln
from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.gait.motion import gait, random_states
from exo_bench.models.mechanism.presets import exo5, random_tree

# 50 seeded random trees: n = 1..4 links, 2D and 3D, random parents and signs.
TREES = [(1 + seed % 4, dim, seed) for dim in (2, 3) for seed in range(100, 125)]


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_inverse_dynamics_agrees_with_pinocchio_on_random_trees(n, dim, seed):
    """Within the float64 error model of tests/conftest.py."""
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 30, seed)
    assert_forces_agree(
        prepare(m, "lagrange").inverse_dynamics(q, qd, qdd),
        prepare(m, "pinocchio").inverse_dynamics(q, qd, qdd),
        m,
        q,
        qd,
        qdd,
    )


@pytest.mark.parametrize("n,dim,seed", TREES[1::8])
def test_mass_matrix_and_bias_agree_with_pinocchio(n, dim, seed):
    """Lagrange's d tau / d qdd against CRBA, and its tau(qdd = 0) against nonLinearEffects."""
    m = random_tree(n, dim, seed)
    q, qd, _ = random_states(m, 10, seed + 1)
    lagrange, pinocchio = prepare(m, "lagrange"), prepare(m, "pinocchio")
    assert_mass_matrices_agree(lagrange.mass_matrix(q), pinocchio.mass_matrix(q), m, q)
    assert_forces_agree(lagrange.bias_forces(q, qd), pinocchio.bias_forces(q, qd), m, q, qd, None)


@pytest.mark.parametrize("n,dim,seed", [(3, 2, 50), (4, 3, 51)])
def test_power_balance_along_smooth_random_motion(n, dim, seed):
    """d(T + Pi)/dt = tau . qd with T and Pi summed over the point masses (models.kinematics)."""
    assert power_balance_residual(ln.inverse_dynamics, random_tree(n, dim, seed), seed) < POWER_BALANCE_TOL


def test_zero_middle_masses_agree_with_pinocchio():
    m = random_tree(4, 3, 52)
    m = m.replace(masses=tuple((a, 0.0 if i % 2 else b, c) for i, (a, b, c) in enumerate(m.masses)))
    q, qd, qdd = random_states(m, 20, 3)
    assert_forces_agree(ln.inverse_dynamics(m, q, qd, qdd), pb.inverse_dynamics(m, q, qd, qdd), m, q, qd, qdd)


def test_cli_lagrange_agrees_with_pinocchio_on_the_exo5_gait(tmp_path, capsys):
    m = exo5(3)
    mo = gait(m, np.linspace(0.0, 1.1, 23))
    states = tmp_path / "states.json"
    states.write_text(json.dumps({"q": mo.q.tolist(), "qd": mo.qd.tolist(), "qdd": mo.qdd.tolist()}))
    out = {}
    for method in ("lagrange", "pinocchio"):
        assert main(["inverse", "exo5-3d", str(states), "--method", method]) == 0
        out[method] = np.array(json.loads(capsys.readouterr().out)["tau"])
    assert out["lagrange"].shape == (23, 15)
    assert_forces_agree(out["lagrange"], out["pinocchio"], m, mo.q, mo.qd, mo.qdd)  # JSON floats: exact round trip


def test_one_sample_and_bad_states():
    m = random_tree(2, 2, 53)
    q, qd, qdd = random_states(m, 1, 0)
    assert ln.inverse_dynamics(m, q[0], qd[0], qdd[0]).shape == (1, 4)
    with pytest.raises(ValueError, match=r"field 'qd'.*expected shape \(samples, 4\)"):
        ln.inverse_dynamics(m, q, qd[:, :3], qdd)
    q[0, 3] = -0.1
    with pytest.raises(ValueError, match="l2"):
        ln.inverse_dynamics(m, q, qd, qdd)
