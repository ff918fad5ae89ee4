"""CasADi functions of the equations and the derivatives of every prepared model (issue 24).

Oracles and error models:

* **Agreement with the numeric kernels** (tau, M, h): the error model of tests/conftest.py,
  ``|a - b| <= K eps term_scale``: the CasADi functions evaluate the same closed forms as method
  ``matrix-factored`` in another order (CasADi's own ``cos``/``sin``, its sparse products), so
  they are one more float64 implementation. The issue's criterion, 1e-13 relative to the largest
  force, is asserted beside it.
* **Inverse-dynamics derivatives against central differences** of the numeric kernel
  (``(tau(x + h e) - tau(x - h e)) / (x+ - x-)``, with the step actually taken). Truncation: tau is
  a sum of terms, each a product of at most two sines/cosines of an angle (frequency 1 each, or
  ``cos^2 psi_i`` on the diagonal), at most two rod lengths (degree 2 in one length), and a rate
  product (degree 2 in the rates). So ``d^3 tau/dq_k^3`` is 0 for a length or a rate and at most
  ``2^3 = 8`` times the sum of ``|terms|`` for an angle, and the truncation of the central
  difference is ``h^2/6 * 8 S`` (angles), 0 otherwise, with ``S = term_scale`` at the state
  (evaluated with the rates and lengths enlarged by ``h``). Rounding: each evaluation carries at
  most ``K eps S``, so the quotient carries ``K eps S / h``. The CasADi derivative's own
  rounding, ``K eps`` times the scale of the differentiated terms (at most ``2 S / min(l, 1)``
  here, lengths >= 0.3), is below 1e-9 of that at ``h = 1e-5``; the factor 2 on the rounding
  term covers it. The bound is derived, not measured; the test also checks that it is tight
  enough to mean something (below 1e-7 of the largest derivative).
* **Forward-dynamics derivatives against a complex step** of the numeric forward dynamics
  (the numpy factored kernel and ``numpy.linalg.solve`` on complex arrays, ``h = 1e-30``): no
  subtraction, so the truncation ``h^2 |f'''| / 6`` is below 1e-58 of any realistic ``f'''``,
  and both sides are float64 evaluations of ``X = M^-1 B``. Perturbation theory of a linear
  system: ``|dX| <= cond(M) (|dM| / |M| |X| + |M^-1| |dB|)``, with ``|dM| <= K eps |M|`` and
  ``|dB| <= K eps`` (the derivative's term scale, bounded by ``2 S / min(l, 1)`` as above); in
  norms per sample, with a factor 2 for the two sides.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from cli_runs import run_cli

from conftest import EPS, K, assert_close, assert_forces_agree, assert_mass_matrices_agree, term_scale
from exo_bench import prepare, presets
from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling, signed_gravity
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import random_tree

ca = pytest.importorskip("casadi")

from exo_bench.matrix_method.export.casadi_functions import FUNCTIONS, CasadiEquations, casadi_functions  # noqa: E402

TREES = [random_tree(5, 2, 11), random_tree(6, 3, 12), presets.exo5(dim=3), presets.exo5(dim=2), random_tree(4, 3, 13)]
IDS = [m.name for m in TREES]


def _states(mech, samples=12, seed=3):
    return random_states(mech, samples, seed)


def _rel(a, b) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


# ----------------------------------------------------------------------------- the functions
@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_functions_agree_with_the_numeric_kernels(mech):
    """tau, M and h of the CasADi functions equal the numpy factored kernel (tau, h) and the matrix
    method's A, B, Lambda blocks (M) to the error model, and to 1e-13 relative."""
    E = casadi_functions(mech)
    q, qd, qdd = _states(mech)
    ref = prepare(mech, "matrix-factored", kernel="numpy")
    tau_ref = ref.inverse_dynamics(q, qd, qdd)
    (tau,) = E.evaluate("inverse_dynamics", q, qd, qdd)
    assert_forces_agree(tau, tau_ref, mech, q, qd, qdd, what="casadi tau")
    assert _rel(tau, tau_ref) <= 1e-13
    (M,) = E.evaluate("mass_matrix", q)
    M_ref = prepare(mech, "matrix", kernel="numpy").mass_matrix(q)
    assert_mass_matrices_agree(M, M_ref, mech, q, what="casadi M")
    assert _rel(M, M_ref) <= 1e-13
    (h,) = E.evaluate("bias_forces", q, qd)
    h_ref = ref.bias_forces(q, qd)
    assert_forces_agree(h, h_ref, mech, q, qd, None, what="casadi h")
    assert _rel(h, h_ref) <= 1e-13
    _, _, M_ad = E.evaluate("inverse_dynamics_derivatives", q, qd, qdd)
    np.testing.assert_array_equal(M_ad, M)  # the same expression, d tau / d qdd


@pytest.mark.parametrize("mech", TREES[:3], ids=IDS[:3])
def test_forward_dynamics_inverts_inverse_dynamics(mech):
    """forward_dynamics(q, qd, ID(q, qd, qdd)) = qdd to the conditioning of M: ``|d qdd| <=
    cond(M) (K eps |qdd| + |M^-1| K eps S)`` per sample (a solve with backward error K eps)."""
    E = casadi_functions(mech)
    q, qd, qdd = _states(mech)
    tau = prepare(mech, "matrix-factored", kernel="numpy").inverse_dynamics(q, qd, qdd)
    (a,) = E.evaluate("forward_dynamics", q, qd, tau)
    (M,) = E.evaluate("mass_matrix", q)
    cond = np.linalg.cond(M)
    Minv = np.linalg.norm(np.linalg.inv(M), 2, axis=(1, 2))
    S = term_scale(mech, q, qd, qdd).max(axis=1)
    bound = cond * K * EPS * np.abs(qdd).max(axis=1) + Minv * K * EPS * S * math.sqrt(mech.dof)
    err = np.abs(a - qdd).max(axis=1)
    assert (err <= 2 * bound).all(), (err / bound).max()


# ----------------------------------------------------------------------------- derivatives
def _central(f, x, k, h):
    """Central difference of ``f`` along coordinate ``k`` with the step actually taken."""
    xp, xm = x.copy(), x.copy()
    xp[:, k] += h * np.maximum(1.0, np.abs(x[:, k]))
    xm[:, k] -= h * np.maximum(1.0, np.abs(x[:, k]))
    return (f(xp) - f(xm)) / (xp[:, k] - xm[:, k])[:, None]


@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_inverse_dynamics_derivatives_against_central_differences(mech):
    """d tau/d q and d tau/d qd of ``model.derivatives`` against central differences of inverse
    dynamics computed independently, by Pinocchio's RNEA (and of the numeric kernel), within the
    truncation + rounding bound of the module docstring (conftest's term scale covers Pinocchio's
    rounding)."""
    model = prepare(mech, "matrix-factored", kernel="numpy")
    q, qd, qdd = _states(mech, samples=6, seed=5)
    jq, jqd, M = model.derivatives.inverse_dynamics(q, qd, qdd)
    for ref in (prepare(mech, "pinocchio"), model):
        _against_central_differences(mech, ref, q, qd, qdd, jq, jqd)


def _against_central_differences(mech, ref, q, qd, qdd, jq, jqd):
    ID = lambda a, b, c: ref.inverse_dynamics(a, b, c, check=False)
    h = 1e-5
    n = mech.nlinks
    grow = h * np.maximum(1.0, np.abs(q)).max() * 2
    S = term_scale(mech, q + np.where(np.arange(mech.dof) >= mech.dof - n, grow, 0.0), np.abs(qd) + grow, qdd)
    angles = np.arange(mech.dof) < mech.dof - n
    worst = 0.0
    for k in range(mech.dof):
        trunc_q = (h * max(1.0, np.abs(q[:, k]).max())) ** 2 / 6 * 8 * S if angles[k] else 0.0 * S
        step_q = h * np.maximum(1.0, np.abs(q[:, k]))[:, None]
        step_qd = h * np.maximum(1.0, np.abs(qd[:, k]))[:, None]
        for J, x, step, trunc, f in (
            (jq, q, step_q, trunc_q, lambda x: ID(x, qd, qdd)),
            (jqd, qd, step_qd, 0.0 * S, lambda x: ID(q, x, qdd)),
        ):
            fd = _central(f, x, k, h)
            bound = 1.01 * trunc + 2 * K * EPS * S / step
            assert (bound <= 1e-7 * np.abs(J).max()).all(), "the bound would not test anything"
            err = np.abs(J[:, :, k] - fd)
            worst = max(worst, float((err / bound).max()))
            assert (err <= bound).all(), f"column {k}: {(err / bound).max():.3g} x the bound"
    assert worst > 0


def _complex_inverse(mech, q, qd, qdd):
    """The numpy factored kernel (what matrix-factored's numpy kernel runs) on complex arrays."""
    kernel = numeric._factored_2d if mech.dim == 2 else numeric._factored_3d
    c, nu = signed_coupling(mech), signed_gravity(mech)[:, None]
    return kernel(mech.nlinks, mech.g, c, nu, q.T, qd.T, qdd.T).T


def _step(q, k, h):
    e = np.zeros(q.shape, dtype=complex)
    e[:, k] = 1j * h
    return e


@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_inverse_dynamics_derivatives_against_complex_step(mech):
    """d tau/d q and d tau/d qd of ``model.derivatives`` equal a complex step (h = 1e-30) of the
    numeric kernel to 1e-13 relative and to ``K eps D``. Both sides evaluate the derivative of the
    same terms in float64 (a complex step subtracts nothing; its truncation, h^2/6 times the third
    derivative, is below 1e-58 of it). ``D``, the sum of the magnitudes of the differentiated terms,
    is at most ``2 S`` for an angle (each term has degree <= 2 in the sines and cosines of one
    angle), ``2 S / l_k`` for a length and ``2 S / |qd_k|`` for a rate (degree <= 2), with
    ``S = term_scale``."""
    model = prepare(mech, "matrix-factored", kernel="numpy")
    q, qd, qdd = _states(mech, samples=6, seed=6)
    jq, jqd, _ = model.derivatives.inverse_dynamics(q, qd, qdd)
    n, d, h = mech.nlinks, mech.dof, 1e-30
    S = term_scale(mech, q, qd, qdd)
    z = lambda x: x.astype(complex)
    cs_q = np.stack([_complex_inverse(mech, q + _step(q, k, h), z(qd), z(qdd)).imag / h for k in range(d)], -1)
    cs_qd = np.stack([_complex_inverse(mech, z(q), qd + _step(q, k, h), z(qdd)).imag / h for k in range(d)], -1)
    per_q = np.where(np.arange(d) < d - n, 1.0, 1.0 / np.concatenate([np.ones_like(q[:, : d - n]), q[:, -n:]], 1))
    assert_close(jq, cs_q, 2 * S[:, :, None] * per_q[:, None, :], what="dtau_dq")
    assert_close(jqd, cs_qd, 2 * S[:, :, None] / np.abs(qd)[:, None, :], what="dtau_dqd")
    assert _rel(jq, cs_q) <= 1e-13 and _rel(jqd, cs_qd) <= 1e-13


def _complex_forward(mech, q, qd, tau):
    """Forward dynamics in complex arithmetic: the numpy factored kernel (as method
    matrix-factored runs it) for M and h, then ``numpy.linalg.solve``."""
    n, d = mech.nlinks, mech.dof
    kernel = numeric._factored_2d if mech.dim == 2 else numeric._factored_3d
    c, nu = signed_coupling(mech), signed_gravity(mech)[:, None]
    ID = lambda a, b, e: kernel(n, mech.g, c, nu, a.T, b.T, e.T).T
    S = q.shape[0]
    h = ID(q, qd, np.zeros_like(q))
    g = ID(q, np.zeros_like(q), np.zeros_like(q))
    M = np.empty((S, d, d), dtype=q.dtype)
    for k in range(d):
        e = np.zeros_like(q)
        e[:, k] = 1.0
        M[:, :, k] = ID(q, np.zeros_like(q), e) - g
    return np.linalg.solve(M, (tau - h)[..., None])[..., 0]


@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_forward_dynamics_derivatives_against_complex_step(mech):
    """d qdd/d q, d qdd/d qd and d qdd/d tau = M^-1 of ``model.derivatives`` against a complex step
    of the numeric forward dynamics, within the perturbation bound of the module docstring."""
    model = prepare(mech, "pinocchio")
    q, qd, qdd = _states(mech, samples=5, seed=8)
    tau = model.inverse_dynamics(q, qd, qdd)
    a, jq, jqd, Minv = model.derivatives.forward_dynamics(q, qd, tau)
    h = 1e-30
    d = mech.dof
    cs_q, cs_qd, cs_tau = (np.empty((q.shape[0], d, d)) for _ in range(3))
    for k in range(d):
        e = np.zeros((q.shape[0], d), dtype=complex)
        e[:, k] = 1j * h
        cs_q[:, :, k] = _complex_forward(mech, q + e, qd.astype(complex), tau.astype(complex)).imag / h
        cs_qd[:, :, k] = _complex_forward(mech, q.astype(complex), qd + e, tau.astype(complex)).imag / h
        cs_tau[:, :, k] = _complex_forward(mech, q.astype(complex), qd.astype(complex), tau + e).imag / h
    M = model.mass_matrix(q)
    cond = np.linalg.cond(M)
    minv = np.linalg.norm(Minv, 2, axis=(1, 2))
    n = mech.nlinks
    S = term_scale(mech, q, qd, a).max(axis=1) * 2 / np.minimum(q[:, -n:], 1.0).min(axis=1)
    for name, X, ref in (("dqdd_dq", jq, cs_q), ("dqdd_dqd", jqd, cs_qd), ("Minv", Minv, cs_tau)):
        Xn = np.linalg.norm(ref, 2, axis=(1, 2))
        bound = 2 * K * EPS * (cond * Xn + minv * S * math.sqrt(d))
        err = np.linalg.norm(X - ref, 2, axis=(1, 2))
        assert (err <= bound).all(), f"{name}: {(err / bound).max():.3g} x the bound"
        assert (bound <= 1e-4 * Xn).all(), f"{name}: the bound would not test anything"


@pytest.mark.parametrize("method", ["matrix", "matrix-factored", "recurrence", "pinocchio", "lagrange", "matrix-paper"])
def test_every_method_has_derivatives(method):
    """Every method's prepared model has ``.derivatives``: its M (d tau/d qdd) is the method's own
    mass matrix to the error model, its accelerations invert the method's inverse dynamics, and
    ``.source`` says which physics computes them."""
    mech = random_tree(3, 3, 21) if method != "matrix-paper" else random_tree(3, 2, 21)
    model = prepare(mech, method)
    q, qd, qdd = _states(mech, samples=4, seed=9)
    jq, jqd, M = model.derivatives.inverse_dynamics(q, qd, qdd)
    assert jq.shape == jqd.shape == M.shape == (4, mech.dof, mech.dof)
    assert_mass_matrices_agree(M, model.mass_matrix(q), mech, q, k=K * mech.dof, what=method)
    tau = model.inverse_dynamics(q, qd, qdd)
    a, aq, aqd, Minv = model.derivatives.forward_dynamics(q, qd, tau)
    assert _rel(a, qdd) <= 1e-10
    np.testing.assert_allclose(Minv @ M, np.broadcast_to(np.eye(mech.dof), M.shape), atol=1e-10)
    src = model.derivatives.source  # the analytic provider for every method (issue 36), not CasADi
    assert src.startswith("analytic O(n) derivatives") and ("unique" in src or method in src)
    one = model.derivatives.inverse_dynamics(q[0], qd[0], qdd[0])
    assert [x.shape for x in one] == [(mech.dof, mech.dof)] * 3
    np.testing.assert_array_equal(one[0], jq[0])


# ----------------------------------------------------------------------------- files and inputs
@pytest.mark.parametrize("mech", [presets.exo5(dim=3), random_tree(4, 2, 7)], ids=["exo5-3d", "tree4-2d"])
def test_casadi_export_round_trips(mech, tmp_path):
    """``exo-bench equations MECH --format casadi -o DIR``: every function loads back with CasADi
    alone (``Function.load``) and gives the in-memory function's numbers exactly."""
    rc, out, err = run_cli(
        [
            "equations",
            mech.name if mech.name.startswith("exo5") else _json(mech, tmp_path),
            "--format",
            "casadi",
            "-o",
            tmp_path / "out",
        ]
    )
    assert rc == 0, err
    stem = mech.name
    files = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert files == sorted([f"{stem}_{n}.casadi" for n in FUNCTIONS] + [f"{stem}_casadi.md"])
    E = casadi_functions(mech)
    q, qd, qdd = _states(mech, samples=3)
    args = {
        "q": q.T,
        "qd": qd.T,
        "qdd": qdd.T,
        "tau": prepare(mech, "matrix-factored", kernel="numpy").inverse_dynamics(q, qd, qdd).T,
    }
    for name, (ins, outs) in FUNCTIONS.items():
        f = ca.Function.load(str(tmp_path / "out" / f"{stem}_{name}.casadi"))
        assert f.name_in() == list(ins) and f.name_out() == list(outs)
        got, want = f(*(args[i] for i in ins)), getattr(E, name)(*(args[i] for i in ins))
        got, want = (got, want) if isinstance(got, (list, tuple)) else ([got], [want])
        for g, w in zip(got, want):
            np.testing.assert_array_equal(np.asarray(g), np.asarray(w))
    note = (tmp_path / "out" / f"{stem}_casadi.md").read_text()
    assert "Function.load" in note and f"{stem}_inverse_dynamics.casadi" in note


def _json(mech, tmp_path):
    p = tmp_path / "mech.json"
    p.write_text(mech.to_json())
    return p


def test_functions_take_symbols():
    """The functions compose with CasADi symbols (what an optimal-control problem does): the mass
    matrix of an MX call equals the function's, and d tau/d q of the SX expression equals the
    derivative function."""
    mech = presets.exo5(dim=2)
    E = casadi_functions(mech)
    q = ca.MX.sym("q", mech.dof)
    M = ca.Function("M", [q], [E.mass_matrix(q)])
    x = _states(mech, samples=1)[0][0]
    np.testing.assert_array_equal(np.asarray(M(x)), np.asarray(E.mass_matrix(x)))
    assert E.inverse_dynamics.expand().n_instructions() > 0  # SX: expandable for IPOPT


def test_bad_input():
    with pytest.raises(ValueError, match="expected a Mechanism"):
        CasadiEquations("exo5-3d")
    model = prepare(presets.exo5(dim=2), "matrix-factored")
    q, qd, qdd = _states(presets.exo5(dim=2), samples=2)
    with pytest.raises(ValueError, match="qd"):
        model.derivatives.inverse_dynamics(q, qd[:, :3], qdd)
    q_bad = q.copy()
    q_bad[0, -1] = 0.0  # l5 = 0: M singular, forward dynamics undefined
    from exo_bench.models.mechanism.singularity import SingularConfigurationError

    with pytest.raises(SingularConfigurationError, match="link 5"):
        model.derivatives.forward_dynamics(q_bad, qd, qdd)


def test_missing_extra_is_named(monkeypatch, tmp_path):
    """Without CasADi: the derivatives and the export raise a ValueError naming the extra; the CLI
    prints one line and exits 2, writing nothing."""
    import sys

    monkeypatch.setitem(sys.modules, "casadi", None)  # import casadi raises ImportError
    casadi_functions.cache_clear()
    try:
        mech = random_tree(2, 2, 99)
        from exo_bench.matrix_method.derivatives import derivatives_of  # model.derivatives needs no CasADi

        with pytest.raises(ValueError, match=r"extra 'casadi'.*exo-bench\[casadi\]"):
            derivatives_of(mech, "matrix-factored")
        rc, out, err = run_cli(["equations", "exo5-2d", "--format", "casadi", "-o", tmp_path])
        assert rc == 2 and len(err.strip().splitlines()) == 1 and "'casadi'" in err, err
        assert list(tmp_path.iterdir()) == []
    finally:
        casadi_functions.cache_clear()


@pytest.mark.parametrize("mech", TREES[:2], ids=IDS[:2])
def test_parameters_are_an_input(mech, tmp_path):
    """``parameters=True``: at other masses, fractions and g the functions are those of the mechanism
    with these values (the numeric kernel of ``mech.replace(...)``, to the error model); the export
    with ``--symbolic-parameters`` takes ``params`` and its note lists their order and values."""
    from exo_bench.matrix_method.export.casadi_functions import parameter_names, parameter_values

    E = casadi_functions(mech, parameters=True)
    other = mech.replace(
        masses=tuple(tuple(1.3 * x + 0.1 for x in m) for m in mech.masses), n=tuple(0.5 for _ in mech.n), g=1.62
    )
    q, qd, qdd = _states(mech)
    ref = prepare(other, "matrix-factored", kernel="numpy")
    (tau,) = E.evaluate("inverse_dynamics", q, qd, qdd, params=parameter_values(other))
    assert_forces_agree(tau, ref.inverse_dynamics(q, qd, qdd), other, q, qd, qdd, what="tau(params)")
    (M,) = E.evaluate("mass_matrix", q, params=parameter_values(other))
    assert_mass_matrices_agree(M, prepare(other, "matrix", kernel="numpy").mass_matrix(q), other, q)
    (same,) = E.evaluate("inverse_dynamics", q, qd, qdd)  # default: the mechanism's own values
    assert_forces_agree(
        same, prepare(mech, "matrix-factored", kernel="numpy").inverse_dynamics(q, qd, qdd), mech, q, qd, qdd
    )
    assert len(parameter_names(mech)) == E.params.numel() == 4 * mech.nlinks + 1
    rc, _, err = run_cli(
        ["equations", _json(mech, tmp_path), "--format", "casadi", "--symbolic-parameters", "-o", tmp_path / "out"]
    )
    assert rc == 0, err
    f = ca.Function.load(str(tmp_path / "out" / f"{mech.name}_inverse_dynamics.casadi"))
    assert f.name_in() == ["q", "qd", "qdd", "params"]
    np.testing.assert_array_equal(np.asarray(f(q[0], qd[0], qdd[0], parameter_values(other))).ravel(), tau[0])
    note = (tmp_path / "out" / f"{mech.name}_casadi.md").read_text()
    assert ", ".join(parameter_names(mech)) in note and "--symbolic-parameters" in note
    with pytest.raises(ValueError, match="without parameters"):
        casadi_functions(mech).evaluate("inverse_dynamics", q, qd, qdd, params=parameter_values(other))


def test_the_derivatives_example_runs_and_checks_itself(tmp_path):
    """The gallery's derivatives example (docs/examples/plot_03_derivatives.py; it was the README's
    "Derivatives and CasADi" section before the README's rewrite), run as a user would run it, with CasADi
    installed: its asserts compare the derivatives with the model's own M, central differences, forward
    dynamics, and CasADi's Jacobian of the exported function."""
    import subprocess
    import sys

    script = Path(__file__).resolve().parent.parent / "docs" / "examples" / "plot_03_derivatives.py"
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "analytic O(n) derivatives" in r.stdout  # model.derivatives.source: the analytic provider (issue 36)
    assert "CasADi's Jacobian vs the analytic one" in r.stdout  # the CasADi check ran, not skipped
