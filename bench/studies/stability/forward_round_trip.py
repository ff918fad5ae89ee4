"""Forward-dynamics study, the round trip: controls from inverse dynamics drive forward dynamics, and the
integrated motion is compared with the prescribed one and with an a-priori bound from the variational equations.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from dataclasses import dataclass
import math

import numpy as np

from exo_bench.api import PreparedSet
from exo_bench.bench.studies.stability.forward_cases import ATOL_FACTOR, EPS, RoundTripCase, TIGHTER, _models, _state0
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.simulation.forward_dynamics import Simulation, make_rhs, simulate
from exo_bench.models.mechanism.mechanism import Mechanism


@dataclass
class Variational:
    """The linearised flow ``Phi(t) = dy(t)/dy(0)`` along a controlled trajectory, from ``2 dof``
    perturbed copies integrated together with the nominal one (forward differences, ``delta``)."""

    dof: int
    delta: float
    solution: Callable[[Any], np.ndarray]  # scipy OdeSolution: times -> states
    horizon: float

    def phi(self, t) -> np.ndarray:
        """``(N, m, m)`` for an array of times (``m = 2 dof``)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        m = 2 * self.dof
        Z = self.solution(t).reshape(m, m + 1, -1)  # (state, copy, time)
        return np.moveaxis((Z[:, 1:] - Z[:, :1]) / self.delta, -1, 0)

    def growth(self, t) -> np.ndarray:
        """``||Phi_q(t)||_inf``: how much a state perturbation at 0 can move q at ``t``."""
        return np.abs(self.phi(t)[:, : self.dof]).sum(-1).max(-1)

    def max_growth(self, samples: int = 41) -> float:
        return float(self.growth(np.linspace(0, self.horizon, samples)).max())


def variational(
    mech: Mechanism,
    controls: fd.Controls,
    q0,
    qd0,
    horizon: float,
    method: str = "pinocchio",
    delta: float = 1e-7,
    rtol: float = 1e-12,
    models: PreparedSet | None = None,
) -> Variational:
    """Integrate the nominal state and ``2 dof`` copies perturbed by ``delta`` in one vectorised
    ODE (DOP853, tight tolerance): each copy is one column of the vectorised right-hand side."""
    from scipy.integrate import solve_ivp

    d = mech.dof
    m = 2 * d
    rhs, _ = make_rhs(_models(models)(mech, method), controls)
    y0 = np.concatenate([np.asarray(q0, float).ravel(), np.asarray(qd0, float).ravel()])
    Z0 = y0[:, None] + delta * np.hstack([np.zeros((m, 1)), np.eye(m)])
    sol = solve_ivp(
        lambda t, z: rhs(t, z.reshape(m, m + 1)).ravel(),
        (0.0, horizon),
        Z0.ravel(),
        method="DOP853",
        rtol=rtol,
        atol=rtol * 1e-2,
        dense_output=True,
    )
    if sol.status != 0:
        raise RuntimeError(f"variational equations of {mech.name}: {sol.message}")
    return Variational(d, delta, sol.sol, horizon)


def a_priori_bound(var: Variational, sim: Simulation, checkpoints: int = 12) -> float:
    """First-order worst case of the global error in q, ``max_j sum_{k<=j} |Phi(t_j) Phi(t_k)^-1|_q
    sqrt(m) (atol + rtol max(|y_k-1|, |y_k|))``: every accepted step's local error passes scipy's RMS
    test, so each component is below ``sqrt(m)`` times its scale, and is propagated by the
    linearised flow. Evaluated at ``checkpoints`` step times (the sum is O(N^2) in the steps)."""
    if sim.steps == 0:
        return 0.0
    d, m = var.dof, 2 * var.dof
    P = var.phi(sim.t)  # (N, m, m)
    inv = np.linalg.inv(P)
    sc = sim.atol + sim.rtol * np.maximum(np.abs(sim.y[:-1]), np.abs(sim.y[1:]))  # (N-1, m), step k -> k-1
    w = math.sqrt(m) * sc
    N = len(sim.t)
    best = 0.0
    for j in np.unique(np.linspace(1, N - 1, checkpoints).round().astype(int)):
        A = np.abs(np.einsum("ab,kbc->kac", P[j, :d], inv[1 : j + 1]))  # (j, d, m): Phi(t_j, t_k), q rows
        best = max(best, float(np.einsum("kac,kc->a", A, w[:j]).max()))
    return best


@dataclass
class RoundTrip:
    case: str
    method: str
    integrator: str
    rtol: float
    sim: Simulation
    error: float = math.nan  # max over accepted steps of |q - q*| (rad or m)
    estimate: float = math.nan  # E: max |q_rtol - q_tighter| at the same times
    floor: float = math.nan  # F: round-off floor
    bound: float = math.nan  # a priori first-order worst case
    growth: float = math.nan  # G(H)
    note: str = ""

    @property
    def tolerance(self) -> float:
        return 2.0 * self.estimate + self.floor

    @property
    def passed(self) -> bool:
        return self.sim.ok and math.isfinite(self.error) and self.error <= self.tolerance

    @property
    def verdict(self) -> str:
        if not self.sim.ok:
            return self.sim.status
        if not math.isfinite(self.estimate):
            return "n/a (no tighter run)"
        return "pass" if self.passed else "FAIL"


def round_trip_run(
    case: RoundTripCase,
    integrator: str,
    rtol: float,
    method: str = "pinocchio",
    control_method: str = "pinocchio",
    max_seconds: float | None = None,
    controls: fd.Controls | None = None,
    models: PreparedSet | None = None,
    jacobian: str = "finite-difference",
) -> Simulation:
    """One integration of the round trip (dense output, so that it can serve as the tighter run
    of another): the forward dynamics of ``method`` driven by ``control_method``'s inverse
    dynamics along the case's motion (or by ``controls`` when given), from the motion's initial
    state; ``jacobian`` of the implicit integrators (:data:`exo_bench.models.simulation.forward_dynamics.JACOBIANS`)."""
    mech = case.mechanism
    models = _models(models)
    ctrl = controls or fd.prescribed_controls(models(mech, control_method), case.motion_of_t)
    q0, qd0 = _state0(case.motion_of_t(np.array([0.0])))
    return simulate(
        models(mech, method),
        q0,
        qd0,
        (0.0, case.horizon),
        ctrl,
        integrator,
        rtol,
        ATOL_FACTOR * rtol,
        max_seconds=max_seconds,
        dense=True,
        jacobian=jacobian,
    )


def round_trip(
    case: RoundTripCase,
    integrator: str,
    rtol: float,
    method: str = "pinocchio",
    control_method: str = "pinocchio",
    var: Variational | None = None,
    sim: Simulation | None = None,
    tighter: Simulation | None = None,
    estimate: bool = True,
    max_seconds: float | None = None,
    controls: fd.Controls | None = None,
    models: PreparedSet | None = None,
) -> RoundTrip:
    """Drive the forward dynamics of ``method`` with the controls of ``control_method``'s inverse
    dynamics along ``case``'s motion and compare with the motion (see :data:`ROUND_TRIP_RULE`).

    ``sim`` and ``tighter`` (the same at ``rtol / TIGHTER``) are run when not given (``tighter``
    only with ``estimate``); ``var`` adds the growth, floor and a priori bound. Without an
    estimate the pass criterion is not evaluated (``passed`` is False, ``note`` says why).
    """
    mech = case.mechanism
    d = mech.dof
    if sim is None:
        sim = round_trip_run(case, integrator, rtol, method, control_method, max_seconds, controls, models)
    rt = RoundTrip(case.name, method, integrator, rtol, sim)
    if not sim.ok:
        return rt
    rt.error = float(np.abs(sim.q(d) - case.motion_of_t(sim.t).q).max())
    if tighter is None and estimate:
        tighter = round_trip_run(
            case, integrator, rtol / TIGHTER, method, control_method, max_seconds, controls, models
        )
    if tighter is None:
        rt.note = "no tighter run: pass criterion not evaluated"
    elif tighter.ok and tighter.solution is not None:
        rt.estimate = float(np.abs(sim.q(d) - tighter.solution(sim.t)[:d].T).max())
    else:
        rt.note = f"no error estimate: tighter run {tighter.status}"
    if var is not None:
        rt.growth = var.max_growth()
        rt.floor = sim.steps * rt.growth * EPS * float(np.abs(sim.y).max())
        rt.bound = a_priori_bound(var, sim)
    else:
        rt.floor = sim.steps * EPS * float(np.abs(sim.y).max())
    return rt
