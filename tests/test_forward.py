"""The forward-dynamics experiments (bench/studies/stability/forward_*.py): the round trip recovers the prescribed
motion within its stated tolerance (and a wrong control does not), the conservative case keeps
its energy within the bound derived from rtol, stiff rods are solved by the implicit
integrators while the explicit ones hit the stability limit."""

import math

import numpy as np

from exo_bench import prepare
import pytest

from exo_bench.bench.studies.stability import forward_cases, forward_evaluation, forward_round_trip
from exo_bench.api import METHODS
from exo_bench.models.simulation import forward_dynamics as fd


@pytest.fixture(scope="module")
def gait_case():
    """The planar gait of the five-link exoskeleton, 0.3 s, with the parameters the case describes
    (T = 1.1 s: paper-assumed-v1; the shipped gait is now the fitted winter-fit-v1)."""
    from exo_bench.models.gait.motion import PAPER_ASSUMED_V1, planar_gait

    c = forward_cases.round_trip_cases()[0]
    return forward_cases.RoundTripCase(
        c.name, c.mechanism, lambda t: planar_gait(c.mechanism, t, PAPER_ASSUMED_V1), c.horizon, c.description
    )


@pytest.fixture(scope="module")
def gait_flow(gait_case):
    ctrl = fd.prescribed_controls(prepare(gait_case.mechanism, "pinocchio"), gait_case.motion_of_t)
    m0 = gait_case.motion_of_t(np.array([0.0]))
    return forward_round_trip.variational(gait_case.mechanism, ctrl, m0.q, m0.qd, gait_case.horizon)


@pytest.mark.parametrize("integrator, rtol", [("DOP853", 1e-8), ("Radau", 1e-6), ("RK45", 1e-7), ("BDF", 1e-7)])
def test_controls_from_inverse_dynamics_reproduce_the_planar_gait(gait_case, gait_flow, integrator, rtol):
    rt = forward_round_trip.round_trip(gait_case, integrator, rtol, var=gait_flow)
    assert rt.sim.ok, rt.sim.status
    assert rt.error <= rt.tolerance, (rt.error, rt.estimate, rt.floor)
    assert rt.error <= rt.bound  # the a priori first-order worst case holds too
    assert rt.error < 1e-5  # and the motion is recovered, in absolute terms (rad, m)


def test_a_wrong_control_is_caught_by_the_round_trip_tolerance(gait_case, gait_flow):
    """Controls off by one part in 1e5 (a tiny modelling error) break the rule: the deviation no
    longer follows the integrator's error. The stated tolerance is sharp enough to tell."""
    good = fd.prescribed_controls(prepare(gait_case.mechanism, "pinocchio"), gait_case.motion_of_t)
    wrong = lambda t, q, qd: good(t, q, qd) * (1 + 1e-5)  # noqa: E731
    rt = forward_round_trip.round_trip(gait_case, "DOP853", 1e-8, var=gait_flow, controls=wrong)
    assert rt.sim.ok
    assert rt.error > 10 * rt.tolerance


def test_round_trip_in_3d_with_every_registered_method():
    """Forward dynamics from each method's own M and h, driven by Pinocchio's inverse dynamics, on a
    3D random tree: the methods that agree with RNEA pass, the literal eq. (18) does not."""
    case = next(c for c in forward_cases.round_trip_cases() if c.name == "tree4-3d random motion")
    case = forward_cases.RoundTripCase(case.name, case.mechanism, case.motion_of_t, 0.3, case.description)
    assert {"pinocchio", "lagrange", "matrix", "matrix-paper", "recurrence"} <= set(METHODS)
    for m in ("pinocchio", "lagrange", "matrix", "recurrence"):
        rt = forward_round_trip.round_trip(case, "DOP853", 1e-8, method=m)
        assert rt.verdict == "pass", (m, rt.error, rt.tolerance, rt.sim.status)
    rt = forward_round_trip.round_trip(case, "DOP853", 1e-8, method="matrix-paper")
    assert rt.verdict == "FAIL" and rt.error > 1e-3


@pytest.mark.parametrize("integrator, rtol", [("DOP853", 1e-7), ("RK45", 1e-6), ("Radau", 1e-6), ("BDF", 1e-6)])
def test_passive_exoskeleton_conserves_energy_within_the_bound_from_rtol(integrator, rtol):
    case = forward_cases.conservative_cases()[0]
    case = forward_cases.SpringCase(
        case.name, case.mechanism, case.q0, case.qd0, case.k, case.c, case.l_rest, 0.25, case.description
    )
    run = forward_evaluation.energy_drift(case, integrator, rtol)
    assert run.sim.ok
    assert run.scale > 10  # the fall does exchange energy (J) ...
    assert run.drift <= run.bound  # ... yet T + Pi + V_spring stays within the bound
    assert run.drift < 1e-3 * run.scale


def test_energy_drift_shrinks_with_the_tolerance():
    case = forward_cases.conservative_cases()[0]
    case = forward_cases.SpringCase(
        case.name, case.mechanism, case.q0, case.qd0, case.k, case.c, case.l_rest, 0.25, case.description
    )
    loose, tight = (forward_evaluation.energy_drift(case, "DOP853", r) for r in (1e-5, 1e-9))
    assert tight.drift < loose.drift / 100 and tight.bound < loose.bound / 100


def test_stiff_rods_are_solved_by_implicit_integrators_and_not_by_explicit_ones():
    """k = 1e8 N/m: the fastest rod mode decays at ~9e3 1/s. An explicit method is stable only for
    h below ~3 / 9e3 s, i.e. more than 1e3 steps (6e3 evaluations of RK45) per 0.5 s; Radau and
    BDF take steps set by the slow pendulum motion."""
    case = forward_cases.stiff_case(1e8, horizon=0.5)
    budget = 5000
    runs = {i: forward_evaluation.stiff_run(case, i, 1e-6, budget) for i in ("Radau", "BDF", "RK45")}
    assert runs["Radau"].solved and runs["BDF"].solved
    assert runs["Radau"].sim.nfev < budget / 2 and runs["BDF"].sim.nfev < budget / 2
    assert not runs["RK45"].solved and "budget" in runs["RK45"].sim.status
    assert runs["RK45"].stiffness > 5e3
    # the two implicit solutions agree: the damped hanging chain does not amplify perturbations much
    # (pendulum rate sqrt(g/l) < 10 1/s mixes angles and rates), so each global error stays within
    # 10 * steps * sqrt(m) * (atol + rtol |y|)
    d = case.mechanism.dof
    m = 2 * d
    r, b = runs["Radau"].sim, runs["BDF"].sim
    scale = 1e-6 * (forward_cases.ATOL_FACTOR + max(np.abs(r.y).max(), np.abs(b.y).max()))
    allowed = 10 * (r.steps + b.steps) * math.sqrt(m) * scale
    assert np.abs(r.y[-1, :d] - b.y[-1, :d]).max() < allowed
    # the dampers only dissipate: T + Pi + springs never rises beyond the integration error
    for run in (runs["Radau"], runs["BDF"]):
        assert run.energy_change <= forward_evaluation.energy_bound(case, run.sim)
