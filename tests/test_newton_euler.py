"""Method ``newton-euler``: agreement with every other method and with the 50-digit reference, its
two kernels, its mass matrix, and its forward dynamics' singular configurations.

Every agreement uses the error model of tests/conftest.py (``K eps term_scale``, the mass coupling
recomputed from the point masses by :func:`conftest.mass_coupling_oracle`): newton-euler computes
the same terms (a mass sum times at most two lengths times an acceleration, a squared rate or g)
along another path, the subtree sums of the virtual-work reference.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import assert_forces_agree, assert_mass_matrices_agree, mass_coupling_oracle

from exo_bench import prepare
from exo_bench.bench.cli import main
from exo_bench.models.mechanism import virtual_work as vw
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.motion import random_states
from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.passes import prepare_tree, solve_coupling
from exo_bench.models.machine.numba_runtime import PARALLEL_MIN_SAMPLES, SAMPLES_PER_TASK
from exo_bench.models.mechanism.presets import exo5, random_tree
from exo_bench.models.mechanism.singularity import SingularConfigurationError

#: Seeded random trees (n, dim, seed): between them several roots and signs -1 in 2D and 3D
#: (checked by test_the_trees_cover_roots_and_signs).
TREES = [(1, 2, 0), (4, 2, 1), (7, 2, 2), (9, 2, 11), (1, 3, 3), (5, 3, 4), (8, 3, 5), (9, 3, 12)]
KERNELS = ("numba", "numpy")


def test_the_trees_cover_roots_and_signs():
    for dim in (2, 3):
        ms = [random_tree(n, d, s) for n, d, s in TREES if d == dim]
        assert any(sum(p < 0 for p in m.parent) >= 2 for m in ms), dim
        assert any(-1 in m.sign for m in ms), dim


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_agrees_with_every_method_and_the_50_digit_reference(n, dim, seed):
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 6, seed)
    others = {
        name: prepare(m, name).inverse_dynamics(q, qd, qdd)
        for name in ("pinocchio", "matrix", "matrix-factored", "recurrence")
    }
    others["virtual-work (50 digits)"] = vw.inverse_dynamics(m, q, qd, qdd)
    if n <= 2:
        others["lagrange"] = prepare(m, "lagrange").inverse_dynamics(q, qd, qdd)
    for kernel in KERNELS:
        tau = prepare(m, "newton-euler", kernel=kernel).inverse_dynamics(q, qd, qdd)
        for name, ref in others.items():
            assert_forces_agree(tau, ref, m, q, qd, qdd, what=f"newton-euler ({kernel}) vs {name}")


@pytest.mark.parametrize("dim", [2, 3])
def test_agrees_on_the_paper_model_with_a_reversed_branch(dim):
    m = exo5(dim)
    assert -1 in m.sign
    q, qd, qdd = random_states(m, 8, 3)
    ref = prepare(m, "pinocchio")
    for kernel in KERNELS:
        ne = prepare(m, "newton-euler", kernel=kernel)
        assert_forces_agree(ne.inverse_dynamics(q, qd, qdd), ref.inverse_dynamics(q, qd, qdd), m, q, qd, qdd)
        assert ne.native_terms
        assert_mass_matrices_agree(ne.mass_matrix(q), ref.mass_matrix(q), m, q, what="M")
        assert_forces_agree(ne.bias_forces(q, qd), ref.bias_forces(q, qd), m, q, qd, None, what="h")


@pytest.mark.slow  # its oracle stays in the default run on smaller trees (docstring)
def test_50_digit_reference_at_a_thousand_links():
    """n = 1000 (3D, a random tree with several roots and signs -1): the O(n) passes against the
    50-digit d'Alembert reference, both kernels, within the same error model. ``slow`` (252 s of the
    README's run at load 8-12): the 50-digit reference of both kernels on random trees of 1-9 links with several
    roots and signs -1 is test_agrees_with_every_method_and_the_50_digit_reference's, and the kernels
    at 800 links against the numpy reference are tests/test_newton_euler_simd.py's."""
    m = random_tree(1000, 3, 7)
    q, qd, qdd = random_states(m, 2, 7)
    ref = vw.inverse_dynamics(m, q, qd, qdd)
    for kernel in KERNELS:
        tau = prepare(m, "newton-euler", kernel=kernel).inverse_dynamics(q, qd, qdd)
        assert_forces_agree(tau, ref, m, q, qd, qdd, what=kernel)


@pytest.mark.parametrize("dim", [2, 3])
def test_numba_kernel_matches_the_numpy_reference_serial_and_threaded(dim):
    """The same arithmetic in another order (loops per sample against vectorised statements): held to
    the error model, through one sample, a batch, and a batch long enough for the threaded driver
    (a block boundary inside), with and without ``out``."""
    m = random_tree(6, dim, 21)
    S = PARALLEL_MIN_SAMPLES + SAMPLES_PER_TASK + 3
    q, qd, qdd = random_states(m, S, 5)
    fast, ref = prepare(m, "newton-euler"), prepare(m, "newton-euler", kernel="numpy")
    a, b = fast.inverse_dynamics(q, qd, qdd), ref.inverse_dynamics(q, qd, qdd)
    assert_forces_agree(a, b, m, q, qd, qdd)
    out = np.empty(m.dof)
    fast.inverse_dynamics(q[3], qd[3], qdd[3], check=False, out=out)
    assert_forces_agree(out[None], b[3:4], m, q[3:4], qd[3:4], qdd[3:4])
    f_fast, f_ref = fast.forward_dynamics(q, qd, b), ref.forward_dynamics(q, qd, b)
    # both invert the same forces: each recovers qdd (the round trip's error model: test_forward_property)
    scale = np.abs(qdd).max() * 1e-9
    assert np.abs(f_fast - qdd).max() < scale and np.abs(f_ref - qdd).max() < scale


def test_the_tree_solve_is_the_inverse_of_the_coupling():
    """``mu^-1 b`` by the tree factor (three O(n) passes) against a dense solve with the oracle's mu."""
    for seed in range(6):
        m = random_tree(12, 3, 40 + seed)
        mu, _ = mass_coupling_oracle(m)
        b = np.random.default_rng(seed).normal(size=(12, 3, 2))
        x = solve_coupling(prepare_tree(m), b)
        ref = np.linalg.solve(mu, b.reshape(12, -1)).reshape(b.shape)
        assert np.abs(x - ref).max() <= 1e3 * np.finfo(float).eps * np.linalg.cond(mu) * np.abs(ref).max()


def test_mass_matrix_is_J_transpose_mu_J():
    m = random_tree(7, 3, 8)
    q, _, _ = random_states(m, 3, 1)
    mu, _ = mass_coupling_oracle(m)
    J = passes.jacobian_columns(prepare_tree(m), 3, q)  # (S, dof, 3)
    dense = np.einsum("sai,ij,sbj->sab", _blocks(J, m), np.kron(mu, np.eye(3)), _blocks(J, m))
    assert_mass_matrices_agree(prepare(m, "newton-euler").mass_matrix(q), dense, m, q)


def _blocks(J, m):
    """``J`` as the dense ``(S, dof, 3n)`` Jacobian ``d r / d q`` (rod i's vector at columns 3i..3i+2)."""
    n = m.nlinks
    S = J.shape[0]
    out = np.zeros((S, m.dof, 3 * n))
    for a in range(m.dof):
        i = a % n
        out[:, a, 3 * i : 3 * i + 3] = J[:, a]
    return out


# ------------------------------------------------------------------ singular configurations
CHAIN = Mechanism(
    dim=3,
    g=9.81,
    parent=(-1, 0, 1),
    sign=(1, -1, 1),
    masses=((1.0, 1.0, 1.0),) * 3,
    n=(0.5, 0.5, 0.5),
    names=("a", "b", "c"),
    name="chain3",
)


def _state(psi2=0.3, l3=0.8):
    q = np.array([0.1, 0.2, 0.3, 0.4, psi2, -0.2, 1.0, 0.9, l3])
    return q, np.full(9, 0.5), np.ones(9)


@pytest.mark.parametrize("method", ["newton-euler", "pinocchio", "matrix-factored"])
@pytest.mark.parametrize("kernel", ["numba", "numpy"])
def test_forward_dynamics_names_vertical_rods_and_zero_lengths(method, kernel):
    if method == "pinocchio" and kernel == "numpy":
        pytest.skip("pinocchio has no kernel option")
    model = prepare(CHAIN, method, **({} if method == "pinocchio" else {"kernel": kernel}))
    q, qd, tau = _state(psi2=math.pi / 2)
    with pytest.raises(ValueError, match=r"link 2 \(b\): vertical rod \(psi2"):
        model.forward_dynamics(q, qd, tau)
    q, qd, tau = _state(l3=0.0)
    with pytest.raises(ValueError, match=r"sample 0: link 3 \(c\): rod length l3 = 0"):
        model.forward_dynamics(q, qd, tau)
    q, qd, tau = _state()
    assert np.isfinite(model.forward_dynamics(q, qd, tau)).all()


def test_forward_dynamics_names_a_link_that_moves_no_mass():
    """A leaf with no middle or end mass: ``M_r`` is singular, found at prepare time (inverse dynamics
    stays defined) and named by forward dynamics; likewise by every other method."""
    m = CHAIN.replace(masses=((1.0, 1.0, 1.0), (1.0, 1.0, 1.0), (1.0, 0.0, 0.0)))
    q, qd, tau = _state()
    ne = prepare(m, "newton-euler")
    assert ne.singular_mass is not None
    assert np.isfinite(ne.inverse_dynamics(q, qd, tau)).all()
    for model in (ne, prepare(m, "newton-euler", kernel="numpy"), prepare(m, "pinocchio")):
        with pytest.raises(SingularConfigurationError, match=r"link 3 \(c\): no mass moves"):
            model.forward_dynamics(q, qd, tau)


def test_cli_forward_at_a_vertical_rod_is_one_line_and_exit_2(tmp_path, capsys):
    m = exo5(3)
    q, qd, qdd = random_states(m, 2, 0)
    tau = prepare(m, "newton-euler").inverse_dynamics(q, qd, qdd)
    good = tmp_path / "s.json"
    good.write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "tau": tau.tolist()}))
    assert main(["forward", "exo5-3d", str(good)]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["method"] == "newton-euler" and np.allclose(got["qdd"], qdd, rtol=0, atol=1e-9)
    q[1, m.nlinks + 2] = math.pi / 2
    bad = tmp_path / "b.json"
    bad.write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "tau": tau.tolist()}))
    for method in ("newton-euler", "matrix-factored"):
        assert main(["forward", "exo5-3d", str(bad), "--method", method]) == 2
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "Traceback" not in err
        assert "sample 1: link 3 (swing_thigh): vertical rod" in err
    nan = tmp_path / "n.json"
    nan.write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": tau.tolist()}))
    assert main(["forward", "exo5-3d", str(nan)]) == 2
    assert "expected an object with keys ['q', 'qd', 'tau']" in capsys.readouterr().err


@pytest.mark.parametrize(
    "method,kernel",
    [("newton-euler", "numba"), ("newton-euler", "numpy"), ("matrix-factored", "numba"), ("pinocchio", None)],
)
def test_forward_dynamics_any_layout_with_check_and_memory_safety_without(method, kernel):
    """``check=True`` converts a Fortran-ordered batch (same accelerations); ``check=False`` refuses
    what is not memory safe (a Fortran-ordered tau, an out too small), naming the field."""
    m = exo5(3)
    q, qd, qdd = random_states(m, 5, 2)
    model = prepare(m, method, **({"kernel": kernel} if kernel else {}))
    tau = model.inverse_dynamics(q, qd, qdd)
    a = model.forward_dynamics(q, qd, tau)
    b = model.forward_dynamics(np.asfortranarray(q), np.asfortranarray(qd), np.asfortranarray(tau))
    assert np.array_equal(a, b)
    with pytest.raises(ValueError, match="field 'tau'"):
        model.forward_dynamics(q, qd, np.asfortranarray(tau), check=False)
    with pytest.raises(ValueError, match="field 'out'"):
        model.forward_dynamics(q, qd, tau, check=False, out=np.empty((1, m.dof)))
    out = np.empty_like(q)
    assert model.forward_dynamics(q, qd, tau, check=False, out=out) is out and np.array_equal(out, a)
