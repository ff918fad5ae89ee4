"""The implicit integrators' analytic Jacobian (models.simulation.simulate.make_jacobian, issue 24).

Oracle: a complex step (h = 1e-30) of the right-hand side ``f(y) = [qd, M^-1 (tau(q, qd) - h)]``
evaluated with the numpy factored kernel and numpy's solve in complex arithmetic, with the rods'
spring-damper controls (linear in the state, so complex-safe). Error model: both sides are float64
evaluations of ``X = M^-1 B`` with ``B`` the derivative of ``tau - h`` (see tests/test_casadi.py):
``|dX| <= 2 K eps (cond(M) |X| + |M^-1| S_B sqrt(dof))``, S_B the derivative term scale.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import EPS, K, term_scale
from exo_bench import prepare
from exo_bench.bench.studies.stability.forward_cases import ATOL_FACTOR, conservative_cases, stiff_case
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.simulation.forward_dynamics import JACOBIANS, make_jacobian, simulate

pytest.importorskip("casadi")

from test_casadi import _complex_forward  # noqa: E402


def _complex_step_jacobian(mech, ctrl, t: float, y: np.ndarray, h: float = 1e-30) -> np.ndarray:
    """``d f / d y`` of ``f = [qd, M^-1 (ctrl(t, q, qd) - h)]`` by a complex step of each state component
    (the controls evaluated on the complex state: linear in it, or independent of it)."""
    d = mech.dof
    cs = np.empty((2 * d, 2 * d))
    for k in range(2 * d):
        z = y.astype(complex)
        z[k] += 1j * h
        q, qd = z[None, :d], z[None, d:]
        a = _complex_forward(mech, q, qd, np.asarray(ctrl(t, q, qd), dtype=complex))
        cs[:, k] = np.concatenate([qd[0], a[0]]).imag / h
    return cs


@pytest.mark.parametrize("case", conservative_cases(), ids=lambda c: c.name)
def test_analytic_jacobian_against_complex_step(case):
    mech = case.mechanism
    d = mech.dof
    model = prepare(mech, "matrix-factored")
    ctrl = case.controls
    jac = make_jacobian(model, ctrl)
    y = np.concatenate([case.q0, case.qd0 + 0.3])
    J = jac(0.0, y)
    cs = _complex_step_jacobian(mech, ctrl, 0.0, y)
    np.testing.assert_array_equal(J[:d], cs[:d])  # d qd / d y: exactly [0, I]
    M = model.mass_matrix(case.q0)
    cond, minv = np.linalg.cond(M), np.linalg.norm(np.linalg.inv(M), 2)
    n = mech.nlinks
    S = term_scale(mech, case.q0, y[d:], None).max() * 2 / min(case.q0[-n:].min(), 1.0) + case.k + np.max(case.c)
    X = np.linalg.norm(cs[d:], 2)
    bound = 2 * K * EPS * (cond * X + minv * S * math.sqrt(d))
    assert np.linalg.norm(J[d:] - cs[d:], 2) <= bound
    assert bound <= 1e-6 * X, "the bound would not test anything"


@pytest.mark.parametrize("t", [0.0, 0.1, 0.18, 0.23, 0.27])
def test_analytic_jacobian_along_the_planar_gait_round_trip(t):
    """The Jacobian of the stability report's Radau/BDF round trip (exo5-2d planar gait, Pinocchio's
    M and h driven by the prescribed controls, whose torques depend on t alone) against a complex step
    of the right-hand side, on the motion's states over the horizon, including 0.18-0.27 s where
    the report's Radau run at rtol 1e-12 spent its extra evaluations. Same error model as above, with
    the accelerations' terms in the scale (d M / d q qdd)."""
    from exo_bench.bench.studies.stability.forward_cases import round_trip_cases

    case = round_trip_cases()[0]
    mech = case.mechanism
    d, n = mech.dof, mech.nlinks
    model = prepare(mech, "pinocchio")
    ctrl = fd.prescribed_controls(model, case.motion_of_t)
    m = case.motion_of_t(np.array([t]))
    y = np.concatenate([m.q[0], m.qd[0]])
    J = make_jacobian(model, ctrl)(t, y)
    cs = _complex_step_jacobian(mech, ctrl, t, y)
    np.testing.assert_array_equal(J[:d], cs[:d])
    M = model.mass_matrix(m.q)[0]
    cond, minv = np.linalg.cond(M), np.linalg.norm(np.linalg.inv(M), 2)
    S = term_scale(mech, m.q, m.qd, m.qdd).max() * 2 / min(m.q[0, -n:].min(), 1.0)
    X = np.linalg.norm(cs[d:], 2)
    bound = 2 * K * EPS * (cond * X + minv * S * math.sqrt(d))
    assert np.linalg.norm(J[d:] - cs[d:], 2) <= bound
    assert bound <= 1e-6 * X, "the bound would not test anything"


def test_analytic_jacobian_reaches_the_tolerance_in_fewer_evaluations():
    """Radau and BDF on the stiff rods (k = 1e6): with the analytic Jacobian the same rtol costs fewer
    right-hand-side evaluations, and the error against a tight reference is the finite-difference
    run's within the report's factor (forward_jacobian.SAME_ERROR: both runs pass scipy's error test
    at the same tolerance)."""
    from exo_bench.bench.studies.stability.forward_report import SAME_ERROR

    case = stiff_case(1e6)
    model = prepare(case.mechanism, "matrix-factored")
    run = lambda integ, r, j: simulate(
        model, case.q0, case.qd0, (0.0, case.horizon), case.controls, integ, r, ATOL_FACTOR * r, jacobian=j
    )
    ref = run("Radau", 1e-10, "analytic")
    assert ref.ok
    n = case.mechanism.nlinks
    for integ in fd.IMPLICIT:
        f, a = run(integ, 1e-4, "finite-difference"), run(integ, 1e-4, "analytic")
        assert f.ok and a.ok and a.jacobian == "analytic" and f.jacobian == "finite-difference"
        assert a.nfev < f.nfev
        # scipy's finite differences take 2 dof columns per Jacobian (more where it refines a column);
        # the analytic Jacobian takes none
        assert f.jacobian_columns >= f.njev * 2 * case.mechanism.dof and a.jacobian_columns == 0
        # the recorded times the report explains its counts with: one per Jacobian scipy counted, and one
        # per single-column call, the rest of nfev being the finite-difference columns
        assert len(f.jacobian_times) == f.njev and len(a.jacobian_times) == a.njev
        assert len(f.call_times) + f.jacobian_columns == f.nfev and len(a.call_times) == a.nfev
        assert f.jacobian_times[0] == a.jacobian_times[0] == 0.0
        ef = np.abs(f.y[-1, :n] - ref.y[-1, :n]).max()
        ea = np.abs(a.y[-1, :n] - ref.y[-1, :n]).max()
        assert ea <= SAME_ERROR * ef and ef <= SAME_ERROR * ea


def test_the_analytic_jacobian_is_current_at_every_step():
    """models.implicit_integrators: with the analytic Jacobian, Radau holds the Jacobian of the state it
    steps from (one evaluation at t0 and one per accepted step, none stale), BDF at least as many, and
    each is the Jacobian at its state: the recorded times are the accepted steps' times. Fails if a scipy
    release renames the attributes the refresh replaces (the count would fall back to scipy's rule, a
    handful per run)."""
    case = stiff_case(1e6)
    model = prepare(case.mechanism, "matrix-factored")
    for integ in fd.IMPLICIT:
        a = simulate(
            model, case.q0, case.qd0, (0.0, case.horizon), case.controls, integ, 1e-6, 1e-8, jacobian="analytic"
        )
        f = simulate(model, case.q0, case.qd0, (0.0, case.horizon), case.controls, integ, 1e-6, 1e-8)
        assert a.ok and f.ok and a.steps > 50
        if integ == "Radau":
            assert a.njev == a.steps + 1
            np.testing.assert_array_equal(a.jacobian_times, a.t)
        else:
            assert a.njev >= a.steps + 1
            assert set(a.t) <= set(a.jacobian_times)
        assert f.njev < f.steps / 2, "scipy's own rule (finite differences) holds its Jacobian across steps"


@pytest.mark.parametrize("integ", [pytest.param(i, marks=pytest.mark.slow) if i == "Radau" else i for i in fd.IMPLICIT])
def test_fewer_evaluations_on_the_planar_gait_at_tight_tolerance(integ):
    """The stability report's round trip (exo5-2d planar gait, Pinocchio's M and h, the prescribed
    controls) at rtol 1e-12, where under scipy's Jacobian-reuse rule the analytic Radau run took more
    evaluations than finite differences: with the Jacobian kept current it takes fewer, and reaches the
    prescribed motion within the report's factor of the finite-difference run's error. Radau's run
    (a minute and a half) is slow: the Jacobian kept current at every Radau step is
    test_the_analytic_jacobian_is_current_at_every_step's, and fewer evaluations at tight tolerance on
    this gait stay in the default run with BDF."""
    from exo_bench.bench.studies.stability.forward_cases import round_trip_cases
    from exo_bench.bench.studies.stability.forward_report import SAME_ERROR
    from exo_bench.bench.studies.stability.forward_round_trip import round_trip_run

    case = round_trip_cases()[0]
    d = case.mechanism.dof
    f, a = (round_trip_run(case, integ, 1e-12, jacobian=j) for j in JACOBIANS)
    assert f.ok and a.ok and a.nfev < f.nfev
    ef, ea = (np.abs(s.q(d) - case.motion_of_t(s.t).q).max() for s in (f, a))
    assert ea <= SAME_ERROR * ef and ef <= SAME_ERROR * ea


def test_bad_jacobian_options():
    case = stiff_case(1e4)
    model = prepare(case.mechanism, "matrix-factored")
    sim = lambda integ, j, ctrl=case.controls: simulate(model, case.q0, case.qd0, (0.0, 0.01), ctrl, integ, jacobian=j)
    with pytest.raises(ValueError, match="'jacobian': expected one of finite-difference, analytic"):
        sim("Radau", "exact")
    with pytest.raises(ValueError, match="only the implicit integrators"):
        sim("DOP853", "analytic")
    with pytest.raises(ValueError, match="controls have no jacobian"):
        sim("Radau", "analytic", lambda t, q, qd: np.zeros_like(q))
