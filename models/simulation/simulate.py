"""Integration of the forward dynamics: :func:`simulate` and its right-hand side, budget and result.

:func:`simulate` integrates ``M(q) qdd + h(q, qd) = controls(t, q, qd)`` (the accelerations of
:mod:`exo_bench.models.simulation.forward_dynamics`) with one of scipy's ``OdeSolver`` classes, stepped here
rather than through ``solve_ivp``, so that a run stopped by its budget keeps the steps it accepted.

**Every argument is validated before any work** (:mod:`exo_bench.models.simulation.simulate_arguments`): a
``ValueError`` names the argument, the expected and the actual value. **There is always a budget**:
at most ``max_evaluations`` right-hand-side evaluations (:data:`DEFAULT_MAX_EVALUATIONS` when not
given) and, optionally, ``max_seconds`` read from ``clock`` (``time.perf_counter`` unless another is
injected, as tests do). Each step evaluates the right-hand side at least once, so the loop ends.
"""

from __future__ import annotations

import math
import time
import traceback
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from exo_bench.models.simulation.external_forces_controls import with_external_forces
from exo_bench.models.simulation.forward_dynamics import Controls, mass_matrix_and_bias, solve_mass_matrix
from exo_bench.models.simulation.implicit_integrators import CURRENT_JACOBIAN
from exo_bench.models.mechanism.mechanism import as_states, split
from exo_bench.models.simulation.simulate_arguments import (
    DEFAULT_MAX_EVALUATIONS,
    IMPLICIT,
    JACOBIANS,
    RTOL_FLOOR,
    check_budget,
    check_simulate_arguments,
)

if TYPE_CHECKING:
    from exo_bench.models.runtime.prepared import PreparedModel

Clock = Callable[[], float]

__all__ = [
    "DEFAULT_MAX_EVALUATIONS",
    "IntegrationBudgetExceeded",
    "JACOBIANS",
    "RTOL_FLOOR",
    "Simulation",
    "make_jacobian",
    "make_rhs",
    "simulate",
]


class IntegrationBudgetExceeded(Exception):
    """The right-hand side was evaluated more often, or for longer, than allowed."""

    def __init__(self, reason: str):
        self.skip_reason = reason
        super().__init__(reason)


@dataclass
class Simulation:
    """The outcome of :func:`simulate`: the accepted steps and what they cost."""

    integrator: str
    rtol: float
    atol: float
    t: np.ndarray  # (N,) accepted step times, t[0] the start
    y: np.ndarray  # (N, 2 dof) states [q, qd] at those times
    nfev: int = 0  # right-hand-side evaluations (columns, for vectorised calls)
    njev: int = 0
    nlu: int = 0
    seconds: float = 0.0
    # "ok", "budget exceeded: ... kept N accepted steps up to t = ...", "failed: ...", "skipped: ..."
    status: str = "ok"
    t_reached: float = math.nan  # the latest time the right-hand side was evaluated at
    outside: int = 0  # trial stages outside the domain (l < 0): NaN, step rejected
    solution: Callable[[Any], np.ndarray] | None = field(
        default=None, repr=False
    )  # dense output (scipy OdeSolution) over the accepted steps, when asked for
    jacobian: str = "finite-difference"  # of the implicit integrators: "finite-difference" (scipy's) or "analytic"
    jacobian_columns: int = 0  # of nfev, the columns spent on scipy's finite-difference Jacobians
    # implicit integrators: the times at which the Jacobian was evaluated (in order), and of every single-column
    # right-hand-side call (stages, Newton iterations, step ends; what the stability report's Jacobian
    # comparison explains its counts with)
    jacobian_times: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    call_times: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    max_evaluations: int = 0  # the budget the run had (0: not run by simulate)
    max_seconds: float | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    @property
    def steps(self) -> int:
        return max(len(self.t) - 1, 0)

    def q(self, dof: int) -> np.ndarray:
        return self.y[:, :dof]

    def qd(self, dof: int) -> np.ndarray:
        return self.y[:, dof:]


def make_rhs(
    model: PreparedModel,
    controls: Controls,
    max_evaluations: int | None = None,
    max_seconds: float | None = None,
    record_times: bool = False,
    clock: Clock = time.perf_counter,
):
    """The vectorised right-hand side ``f(t, y)`` of ``y = [q, qd]``, ``y`` of shape ``(2 dof,)`` or
    ``(2 dof, k)``, and a counter dict (``columns`` evaluated, stages ``rejected`` as outside the
    domain, the latest ``t`` reached; with ``record_times`` the ``times`` of the single-column calls and
    the ``jacobian_times`` of the multi-column ones, scipy's finite-difference Jacobians). Over budget it raises
    :class:`IntegrationBudgetExceeded` (``None``: no limit; elapsed time is read from ``clock``)."""
    check_budget(max_evaluations, max_seconds, allow_none=True)
    mech = model.mechanism
    d = mech.dof
    count: dict[str, Any] = {
        "columns": 0,
        "jacobian_columns": 0,
        "rejected": 0,
        "t": -math.inf,
        "start": clock(),
        "times": array("d"),
        "jacobian_times": array("d"),
    }

    def rhs(t: float, y: np.ndarray) -> np.ndarray:
        Y = y.reshape(2 * d, -1).T  # (k, 2d): one row per column of y
        count["columns"] += Y.shape[0]
        if Y.shape[0] > 1:  # only scipy's finite-difference Jacobian asks for several
            count["jacobian_columns"] += Y.shape[0]
            if record_times:
                count["jacobian_times"].append(t)
        elif record_times:
            count["times"].append(t)
        if max_evaluations is not None and count["columns"] > max_evaluations:
            raise IntegrationBudgetExceeded(
                f"gave up after {max_evaluations} right-hand-side evaluations (t = {t:.4g} s)"
            )
        if max_seconds is not None and clock() - count["start"] > max_seconds:
            raise IntegrationBudgetExceeded(
                f"gave up after {max_seconds:g} s of wall time ({count['columns']} evaluations, t = {t:.4g} s)"
            )
        count["t"] = max(count["t"], t)
        q, qd = np.ascontiguousarray(Y[:, :d]), np.ascontiguousarray(Y[:, d:])
        # A trial stage of a too-long step can leave the domain (a rod length below zero, or not
        # finite): its derivative is NaN, which makes scipy reject the step and shorten it. An
        # integration that cannot get past such states ends with scipy's failure message.
        valid = np.isfinite(Y).all(axis=1) & (split(mech, q)[2] >= 0).all(axis=1)
        qdd = np.full_like(q, np.nan)
        if valid.any():
            qv, qdv = (q, qd) if valid.all() else (q[valid], qd[valid])
            tau = controls(t, qv, qdv)
            M, h = mass_matrix_and_bias(model, qv, qdv)
            qdd[valid] = solve_mass_matrix(M, tau - h)
        count["rejected"] += int((~valid).sum())
        return np.concatenate([qd, qdd], axis=1).T.reshape(y.shape)

    return rhs, count


def make_jacobian(model: PreparedModel, controls: Controls):
    """The analytic Jacobian ``df/dy`` of the right-hand side ``f = [qd, qdd]`` of :func:`make_rhs`:
    ``[[0, I], [dqdd/dq + M^-1 dtau/dq, dqdd/dqd + M^-1 dtau/dqd]]`` with the forward-dynamics
    derivatives of ``model.derivatives`` (:mod:`exo_bench.models.derivatives.derivatives`: the analytic derivatives of
    the Newton-Euler passes and the implicit-function theorem, ``M^-1`` by the O(n) forward dynamics; no
    CasADi) and the controls' own ``controls.jacobian(t, q, qd) -> (dtau/dq, dtau/dqd)``
    (:func:`exo_bench.models.simulation.forward_dynamics.prescribed_controls` and
    :func:`exo_bench.models.simulation.forward_dynamics.rod_spring_damper` have one). A ValueError when the controls have
    none. ``tests/test_integrator_derivatives.py`` checks it against the provider's inverse-dynamics
    derivatives through a dense solve."""
    jac_controls = getattr(controls, "jacobian", None)
    if jac_controls is None:
        raise ValueError(
            "jacobian 'analytic': the controls have no jacobian(t, q, qd) -> (dtau/dq, dtau/dqd) "
            "attribute; use jacobian='finite-difference'"
        )
    derivatives = model.derivatives
    d = model.dof
    eye = np.eye(d)

    def jac(t: float, y: np.ndarray) -> np.ndarray:
        q, qd = y[None, :d], y[None, d:]
        tau = controls(t, q, qd)
        _, aq, aqd, minv = derivatives.forward_dynamics(q, qd, np.ascontiguousarray(tau), check=False)
        cq, cqd = jac_controls(t, q, qd)
        J = np.zeros((2 * d, 2 * d))
        J[:d, d:] = eye
        J[d:, :d] = aq[0] + minv[0] @ cq[0]
        J[d:, d:] = aqd[0] + minv[0] @ cqd[0]
        return J

    return jac


def _solver_class(integrator: str, jacobian: str):
    import scipy.integrate as si

    return CURRENT_JACOBIAN[integrator] if jacobian == "analytic" else getattr(si, integrator)


def _dense(ts: list, interpolants: list, integrator: str):
    """The dense output over the accepted steps, as ``solve_ivp`` builds it."""
    from scipy.integrate import OdeSolution

    try:
        return OdeSolution(ts, interpolants, alt_segment=integrator == "BDF")
    except TypeError:  # scipy < 1.11: no alt_segment
        return OdeSolution(ts, interpolants)


def simulate(
    model: PreparedModel,
    q0,
    qd0,
    t_span: tuple[float, float],
    controls: Controls,
    integrator: str = "DOP853",
    rtol: float = 1e-8,
    atol: float | None = None,
    max_evaluations: int | None = None,
    max_seconds: float | None = None,
    dense: bool = False,
    first_step: float | None = None,
    jacobian: str = "finite-difference",
    clock: Clock = time.perf_counter,
    f_ext: Callable[..., Any] | None = None,
) -> Simulation:
    """Integrate ``M qdd + h = controls(t, q, qd)`` from ``(q0, qd0)`` over ``t_span``.

    * ``t_span``: two finite times, increasing; ``integrator``: one of :data:`INTEGRATORS`;
    * ``rtol``: in ``[RTOL_FLOOR, 1)``, :data:`RTOL_FLOOR` = 100 machine epsilons (scipy's own floor);
      ``atol``: finite and > 0, by default ``rtol * 1e-3`` (a state component of 1e-3 rad or mm counts
      as small);
    * ``max_evaluations``: the budget of right-hand-side evaluations (columns), an integer >= 1;
      ``None`` is the default budget :data:`DEFAULT_MAX_EVALUATIONS` (1,000,000: 90 times the largest
      run of the stability study). ``max_seconds``: an optional wall-time budget, finite and > 0,
      measured on ``clock`` (a function returning seconds, ``time.perf_counter`` by default);
    * ``jacobian`` (implicit integrators): ``"finite-difference"`` (scipy's, from the vectorised
      right-hand side, counted in ``nfev``) or ``"analytic"`` (:func:`make_jacobian`, kept current:
      re-evaluated after every accepted step, :mod:`exo_bench.models.simulation.implicit_integrators`);
    * ``first_step``: ``None`` (scipy chooses) or in ``(0, t_span[1] - t_span[0]]``; ``dense``: a bool.
    * ``f_ext``: external forces at the point masses, ``f_ext(t, q, qd) -> (samples, links, 3, dim)``
      called as the controls are (ground contact, interaction, loads): with it ``M qdd + h = controls + Q(q,
      f_ext)`` (:class:`exo_bench.models.simulation.external_forces_controls.ControlsWithForces`, docs/external-forces.md);
      ``jacobian="analytic"`` needs ``f_ext.jacobian(t, q, qd) -> (df/dq, df/dqd)``.

    Bad arguments raise ValueError before any work. The initial state is validated and checked for a
    singular mass matrix, exactly or to working precision (then
    :class:`exo_bench.models.mechanism.singularity.SingularConfigurationError`: ``model.check_regular``, the
    conditioning test of every method's forward dynamics). A failure during the integration (the budget, an invalid state such as a negative length, a scipy failure) is recorded in
    ``status``, which then says how many accepted steps were kept and up to when: ``t``, ``y`` and
    the dense ``solution`` hold every step accepted before it (the solution may end one step short: a
    budget can stop DOP853 while it evaluates the last step's interpolant).
    """
    a = check_simulate_arguments(
        model,
        t_span,
        controls,
        integrator,
        rtol,
        atol,
        max_evaluations,
        max_seconds,
        dense,
        first_step,
        jacobian,
        clock,
    )
    if f_ext is not None:  # before any work, as every argument
        controls = with_external_forces(model, controls, f_ext, jacobian)
    mech = model.mechanism
    q0, qd0, _ = as_states(mech, q0, qd0, source="initial state")
    model.check_regular(q0)  # exactly singular, or beyond the conditioning bound (models/runtime/conditioning.py)
    rhs, count = make_rhs(
        model, controls, a.max_evaluations, a.max_seconds, record_times=integrator in IMPLICIT, clock=clock
    )
    y0 = np.concatenate([q0[0], qd0[0]])
    kw: dict[str, Any] = {} if a.first_step is None else {"first_step": a.first_step}
    if jacobian == "analytic":
        analytic_jac = make_jacobian(model, controls)

        def jac(t: float, y: np.ndarray) -> np.ndarray:
            count["jacobian_times"].append(t)
            return analytic_jac(t, y)

        kw["jac"] = jac
    ts, ys, interpolants = [a.t_span[0]], [y0], []
    status, solver = "ok", None
    try:
        solver = _solver_class(integrator, jacobian)(
            rhs, a.t_span[0], y0, a.t_span[1], rtol=a.rtol, atol=a.atol, vectorized=True, **kw
        )
        while solver.status == "running":
            message = solver.step()
            if solver.status == "failed":
                status = f"failed: {message}"
                break
            ts.append(solver.t)
            ys.append(solver.y.copy())
            if dense:
                interpolants.append(solver.dense_output())
    except IntegrationBudgetExceeded as e:
        status = f"budget exceeded: {e.skip_reason}"
    except Exception as e:  # noqa: BLE001 - a method over its budget or raising: record, do not crash
        skip = getattr(e, "skip_reason", None)
        status = f"skipped: {skip}" if skip else "failed: " + traceback.format_exception_only(type(e), e)[-1].strip()
    if status != "ok":
        status += f"; kept {len(ts) - 1} accepted steps up to t = {ts[-1]:.6g} s"
    seconds = clock() - count["start"]
    return Simulation(
        integrator,
        a.rtol,
        a.atol,
        np.asarray(ts, dtype=float),
        np.asarray(ys, dtype=float),
        count["columns"],
        int(getattr(solver, "njev", 0) or 0),
        int(getattr(solver, "nlu", 0) or 0),
        seconds,
        status,
        float(count["t"]),
        count["rejected"],
        _dense(ts[: len(interpolants) + 1], interpolants, integrator) if dense and interpolants else None,
        jacobian,
        count["jacobian_columns"],
        np.asarray(count["jacobian_times"]),
        np.asarray(count["times"]),
        a.max_evaluations,
        a.max_seconds,
    )
