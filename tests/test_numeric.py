"""The numeric matrix method (``matrix``) and eq. (18) as printed (``matrix-paper``) against
Lagrange, Pinocchio, power balance, and at the singular configurations."""

import json
import warnings

import numpy as np
import pytest
from conftest import POWER_BALANCE_TOL, assert_close, assert_forces_agree, power_balance_residual, term_scale
import sympy as sp

from exo_bench import prepare
from exo_bench.bench.cli import main
from exo_bench.lagrange import numeric as lagrange_numeric
from exo_bench.bench.studies import errata
from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.matrix_method import printed
from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.gait.motion import gait, random_states
from exo_bench.models.mechanism.presets import exo5, fig5, random_tree

#: 100 seeded random trees: n = 1..6, 2D and 3D, random parents (several roots) and signs.
TREES = [(1 + s % 6, 2 if (s // 6) % 2 == 0 else 3, s) for s in range(100)]
LAGRANGE_MAX_LINKS = 3


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_matrix_method_agrees_with_pinocchio_and_lagrange_on_random_trees(n, dim, seed):
    """Both matrix evaluations (every matrix formed, and the fused kernel) against Pinocchio's RNEA
    and, for small n, Lagrange's equations: within the float64 error model of tests/conftest.py."""
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 8, seed)
    ref = prepare(m, "pinocchio").inverse_dynamics(q, qd, qdd)
    for method in ("matrix", "matrix-factored"):
        tau = prepare(m, method).inverse_dynamics(q, qd, qdd)
        assert_forces_agree(tau, ref, m, q, qd, qdd, what=f"{method} vs pinocchio")
        if n <= LAGRANGE_MAX_LINKS:
            assert_forces_agree(
                tau, lagrange_numeric.inverse_dynamics(m, q, qd, qdd), m, q, qd, qdd, what=f"{method} vs lagrange"
            )


@pytest.mark.parametrize("n,dim,seed", [(3, 2, 1), (6, 2, 2), (4, 3, 3), (7, 3, 4)])
def test_factored_evaluation_equals_the_matrices_times_the_rates(n, dim, seed):
    """The fast path forms no matrix; it must equal eq. (17) with every matrix formed, on every
    tile of samples (3000 samples: several tiles of numeric.TILE)."""
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 3000, seed)
    assert_forces_agree(
        prepare(m, "matrix-factored").inverse_dynamics(q, qd, qdd),
        numeric.inverse_dynamics_from_matrices(m, q, qd, qdd),
        m,
        q,
        qd,
        qdd,
    )


def test_half_angle_sines_and_cosines_are_accurate():
    x = np.random.default_rng(0).uniform(-50, 50, 200_000)
    x[:4] = [0.0, np.pi / 2, np.pi, -np.pi]
    c, s = numeric._cos_sin(x)
    # a few ulps of 1 (numpy's own cos/sin are faithfully rounded: 1 ulp each)
    assert (
        np.abs(c - np.cos(x)).max() <= 4 * np.finfo(float).eps
        and np.abs(s - np.sin(x)).max() <= 4 * np.finfo(float).eps
    )


@pytest.mark.parametrize("n,dim,seed", [(3, 2, 21), (5, 2, 22), (4, 3, 23), (6, 3, 24)])
def test_matrix_method_satisfies_power_balance(n, dim, seed):
    """d(T + Pi)/dt = tau . qd along a smooth motion, T and Pi summed over the point masses."""
    assert power_balance_residual(numeric.inverse_dynamics, random_tree(n, dim, seed), seed) < POWER_BALANCE_TOL


def _singular_states(m, seed):
    """phi_1 - phi_2 = pi/2 (cos(phi_i - phi_j) = 0), cos phi_1 = 0, sin phi_2 = sin phi_3 = 0."""
    q, qd, qdd = random_states(m, 6, seed)
    q[:, : m.nlinks] = [np.pi / 2, 0.0, 0.0, -np.pi / 2][: m.nlinks]
    return q, qd, qdd


@pytest.mark.parametrize("seed", [31, 32, 33])
def test_matrix_is_finite_and_right_where_matrix_paper_divides_by_zero(seed):
    m = random_tree(4, 3, seed)
    q, qd, qdd = _singular_states(m, seed)
    ref = pb.inverse_dynamics(m, q, qd, qdd)
    for method in ("matrix", "matrix-factored"):
        tau = prepare(m, method).inverse_dynamics(q, qd, qdd)
        assert np.isfinite(tau).all()
        assert_forces_agree(tau, ref, m, q, qd, qdd, what=method)
    # sin phi_2 = 0 exactly in floating point: the printed p^l = 2D p^l sin psi / sin phi is 0/0
    with pytest.warns(RuntimeWarning, match="0/0"):
        paper = numeric.inverse_dynamics_paper(m, q, qd, qdd)
    n = m.nlinks
    assert np.isnan(paper[:, 2 * n + 1]).all() and np.isnan(paper[:, 2 * n + 2]).all()


def test_matrix_paper_is_nan_at_exactly_singular_cosines():
    """No double makes cos vanish, so exact arithmetic shows the printed divisions by
    cos(phi_i - phi_j) and cos phi_i: 0/0 at phi_1 = pi/2, phi_2 = 0 on a chain."""
    m = errata.chains(3)[2]
    q = np.array([sp.pi / 2, sp.S.Zero, sp.pi / 3] + [sp.Rational(1, 5)] * 3 + [sp.Rational(1, 2)] * 3, dtype=object)
    exact = numeric.paper_matrices(m, q, exact=True)
    is_nan = lambda x: x is sp.nan
    assert is_nan(exact["psi"]["B"][0, 0, 1]) and is_nan(exact["psi"]["B"][0, 1, 0])  # cos(phi1 - phi2) = 0
    assert is_nan(exact["psi"]["P"][0, 0])  # cos phi_1 = 0
    assert is_nan(exact["l"]["P"][0, 1])  # sin phi_2 = 0
    qf = np.array([float(x) for x in q])[None, :]
    ours = numeric.matrices(m, qf)
    ref = errata.pinocchio_matrices(m, qf)
    for block, name in [("psi", "B"), ("psi", "P"), ("l", "P"), ("l", "E")]:
        assert np.isfinite(ours[block][name]).all()
        # each element is one term: mass times at most two lengths (the scale of the whole matrix)
        assert_close(
            ours[block][name], ref[block][name], np.abs(ref[block][name]).max() + m.total_mass, what=f"{block}.{name}"
        )


def _away_from_singular(m, seed, samples=10):
    """Random states with every divisor of (18) at least 0.05 from zero."""
    q, qd, qdd = random_states(m, 200, seed)
    n = m.nlinks
    phi = q[:, :n]
    C = np.abs(np.cos(phi[:, :, None] - phi[:, None, :])).min(axis=(1, 2))
    ok = (C > 0.05) & (np.abs(np.cos(phi)).min(1) > 0.05) & (np.abs(np.sin(phi)).min(1) > 0.05)
    idx = np.flatnonzero(ok)[:samples]
    assert idx.size == samples
    return q[idx], qd[idx], qdd[idx]


@pytest.mark.parametrize("n,seed", [(2, 41), (3, 42), (4, 43)])
def test_matrix_paper_agrees_wherever_the_printed_formulas_hold(n, seed, rel):
    """2D has no transitions; in 3D the rows of phi and psi use only lines that hold, and the l rows
    agree when psi' = 0, which removes the G_l and K_l terms.

    The printed lines divide by cos(phi_i - phi_j), cos phi_i, sin phi_i, each at least 0.05 here:
    a quotient ``x / d`` times ``d`` again loses up to ``|x| eps / |d|``, a factor 1 / 0.05 = 20 on
    the error model's bound."""
    m2 = random_tree(n, 2, seed)
    q, qd, qdd = random_states(m2, 10, seed)
    assert_forces_agree(
        numeric.inverse_dynamics_paper(m2, q, qd, qdd), pb.inverse_dynamics(m2, q, qd, qdd), m2, q, qd, qdd
    )
    m = random_tree(n, 3, seed)
    q, qd, qdd = _away_from_singular(m, seed)
    ref = pb.inverse_dynamics(m, q, qd, qdd)
    paper = numeric.inverse_dynamics_paper(m, q, qd, qdd)
    scale = 20 * term_scale(m, q, qd, qdd)
    assert_close(paper[:, : 2 * n], ref[:, : 2 * n], scale[:, : 2 * n])
    assert rel(paper[:, 2 * n :], ref[:, 2 * n :]) > 1e-3  # the l rows use g^l and k^l
    qd[:, n : 2 * n] = 0.0
    assert_close(
        numeric.inverse_dynamics_paper(m, q, qd, qdd),
        pb.inverse_dynamics(m, q, qd, qdd),
        20 * term_scale(m, q, qd, qdd),
    )


def test_matrix_paper_disagrees_exactly_by_the_documented_errata(rel):
    """The lines the errata check finds failing, replaced by their corrected forms, make matrix-paper
    agree with Pinocchio; each of those whose values are wrong is needed."""
    witness = [errata.PinocchioWitness()]
    models = [random_tree(3, 3, 51), exo5(3)]
    failing = [
        v.formula.key
        for f in printed.TRANSITIONS
        for v in [errata.check_transition(f, witness, models)]
        if v.status.startswith("fails")
    ]
    assert failing, "eq. (18) as printed has misprints"
    assert all(f.corrected is not None for f in printed.TRANSITIONS if f.key in failing)
    for m in [random_tree(4, 3, 52), fig5(3)]:
        q, qd, qdd = _away_from_singular(m, 53)
        ref = pb.inverse_dynamics(m, q, qd, qdd)
        fixed = numeric.generalised_forces(m, numeric.paper_matrices(m, q, printed.corrected_table(failing)), qd, qdd)
        assert_close(fixed, ref, 20 * term_scale(m, q, qd, qdd))  # divisors >= 0.05: see above
        wrong_values = [k for k in failing if k != "18:k^psi"]  # k^psi: only its label is wrong
        for k in wrong_values:
            partial = printed.corrected_table([x for x in failing if x != k])
            tau = numeric.generalised_forces(m, numeric.paper_matrices(m, q, partial), qd, qdd)
            assert rel(tau, ref) > 1e-3, k


def test_bad_states_are_rejected_with_the_field_and_shape():
    m = exo5(3)
    q, qd, qdd = random_states(m, 3, 1)
    with pytest.raises(ValueError, match=r"field 'qd': expected shape \(samples, 15\)"):
        numeric.inverse_dynamics(m, q, qd[:, :10], qdd)
    q[1, 3] = np.nan
    with pytest.raises(ValueError, match="field 'q' sample 1 coordinate phi4"):
        numeric.inverse_dynamics(m, q, qd, qdd)


def test_cli_inverse_agrees_with_pinocchio_on_the_gait(tmp_path, capsys):
    """``exo-bench inverse exo5-3d STATES.json --method matrix|recurrence`` vs ``--method pinocchio``."""
    mo = gait(exo5(3), np.linspace(0.0, 1.1, 23))
    path = tmp_path / "gait.json"
    path.write_text(json.dumps({"q": mo.q.tolist(), "qd": mo.qd.tolist(), "qdd": mo.qdd.tolist()}))
    out = {}
    for method in ("pinocchio", "matrix", "recurrence"):
        assert main(["inverse", "exo5-3d", str(path), "--method", method]) == 0
        out[method] = np.array(json.loads(capsys.readouterr().out)["tau"])
    for method in ("matrix", "recurrence"):  # JSON prints floats with repr: round trip exact
        assert_forces_agree(out[method], out["pinocchio"], exo5(3), mo.q, mo.qd, mo.qdd, what=method)


def test_matrix_paper_warns_and_returns_nan_on_the_gait_start():
    """The gait of eq. (26) starts with phi_1 = phi_4 = 0: the printed p^l divides 0/0."""
    m = exo5(3)
    mo = gait(m, np.array([0.0, 0.3]))
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        tau = numeric.inverse_dynamics_paper(m, mo.q, mo.qd, mo.qdd)
    assert any("0/0" in str(x.message) for x in w)
    assert np.isnan(tau[0]).any() and np.isfinite(tau[1]).all()
