"""Forward dynamics: accelerations from a method's mass matrix and bias forces, and their integration.

The equations of motion of every method have the form ``M(q) qdd + h(q, qd) = tau``. Forward
dynamics solves them for ``qdd``:

Every function takes a prepared model (:func:`exo_bench.prepare`, :mod:`exo_bench.models.prepared`):

* **Pinocchio** exposes ``M`` (CRBA) and ``h`` (``nonLinearEffects``) directly. Its ABA would be
  faster, but it refuses the mimic joints of the generated URDF, so the suite uses CRBA and a
  solve.
* **Any method** ``tau = ID(q, qd, qdd)`` gives them exactly, because inverse dynamics is
  linear in ``qdd``: ``h = ID(q, qd, 0)`` and ``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)``
  (:func:`exo_bench.models.prepared.terms_from_inverse_dynamics`, one batched call per evaluation); a
  prepared model uses its own terms where it has them (``native_terms``).

**Singular configurations.** ``M = J^T (mu (x) I) J``, where ``J`` maps ``qd`` to the rod
vectors' rates ``d/dt(s_i l_i u_i)`` (per link the columns ``l_i du_i/dphi_i``,
``l_i du_i/dpsi_i``, ``u_i``) and ``mu`` is the mass coupling of eq. (6), the mass distribution
matrix (:func:`exo_bench.models.aggregates.coupling`). ``M`` is singular exactly when ``mu`` is singular or
a link's columns are dependent: a rod of length zero (its angles move no mass) or, in 3D, a vertical rod
(``cos psi_i = 0``: the azimuth column ``l_i cos psi_i (-sin phi_i, cos phi_i, 0)`` vanishes).
Inverse dynamics is still defined there; forward dynamics is not, and
:func:`accelerations` raises :class:`SingularConfigurationError` naming the link instead of
returning NaN or garbage. :func:`singular_reasons` does the detection, exactly (no threshold on
a condition number), and :func:`condition_numbers` measures how close to singular ``M`` is.

**Integration** (:func:`simulate`) uses scipy's ``solve_ivp`` on the state ``y = [q, qd]``, with
explicit (RK45, DOP853) or implicit (Radau, BDF) integrators. The right-hand side is vectorised,
so the implicit integrators' finite-difference Jacobian costs one batched call per column block;
``jacobian="analytic"`` gives them :func:`make_jacobian` instead (the forward-dynamics derivatives
of ``model.derivatives`` and the controls' ``jacobian``), which costs no right-hand-side evaluation
and is therefore re-evaluated after every accepted step (:mod:`exo_bench.models.implicit_integrators`).
"""

from __future__ import annotations

import math
import time
import traceback
from array import array
from dataclasses import dataclass, field
from collections.abc import Callable
from typing import Any

import numpy as np

from exo_bench.models.implicit_integrators import CURRENT_JACOBIAN
from exo_bench.models.mechanism import Mechanism, as_states, split
from exo_bench.models.prepared import PreparedModel, terms_from_inverse_dynamics
from exo_bench.models.singularity import COS_VERTICAL, SingularConfigurationError, singular_reasons  # noqa: F401 - re-exported

#: The explicit and implicit integrators of ``scipy.integrate.solve_ivp`` that the suite uses.
EXPLICIT = ("RK45", "DOP853")
IMPLICIT = ("Radau", "BDF")
INTEGRATORS = EXPLICIT + IMPLICIT

Controls = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


# --------------------------------------------------------------------------- mass matrix and bias
def mass_matrix_and_bias(model: PreparedModel, q: np.ndarray, qd: np.ndarray, via_inverse_dynamics: bool = False):
    """``M (S, dof, dof)`` and ``h (S, dof)`` of a prepared model, on validated ``(S, dof)`` arrays.

    The model's own terms where it has them (``model.native_terms``: Pinocchio's CRBA and
    ``nonLinearEffects``, Lagrange's lambdified ``d tau / d qdd`` and ``tau(qdd = 0)``, the matrix
    method's ``A, B, Lambda`` blocks), else, or with ``via_inverse_dynamics=True``, from its inverse
    dynamics (:func:`exo_bench.models.prepared.terms_from_inverse_dynamics`, one batched call).
    """
    if via_inverse_dynamics:
        return terms_from_inverse_dynamics(
            lambda a, b, c: model.inverse_dynamics(a, b, c, check=False), model.dof, q, qd
        )
    return model.mass_matrix_and_bias(q, qd, check=False)


def condition_numbers(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """2-norm condition numbers of a batch of mass matrices ``(S, dof, dof)``: raw and equilibrated.

    * ``raw = cond(M)`` in SI units (rad and m): the spread of the inertias, hence of the time
      scales of the motion (stiffness), and the digits a plain LU solve of ``M`` can lose.
    * ``equilibrated = cond(D^-1/2 M D^-1/2)`` with ``D = diag(M)``: invariant to the units and
      the scaling of each coordinate. ``inf`` where a diagonal entry is not positive.

    **In exact arithmetic the equilibrated number does not depend on the configuration.** Per link
    the columns of ``J`` are ``s_i R_i N_i`` with ``R_i`` orthogonal (``u_phi/|u_phi|, u_psi, u``)
    and ``N_i = diag(l_i cos psi_i, l_i, 1)``, so ``diag(M)`` holds ``mu_ii N_i^2`` and
    ``D^-1/2 M D^-1/2`` is orthogonally similar to ``(D_mu^-1/2 mu D_mu^-1/2) (x) I_dim``. All the
    configuration dependence of ``cond(M)`` is the scaling ``N`` (short, near-vertical rods); a
    computed ``M`` whose equilibrated number departs from that of ``mu`` has lost its small
    entries (every method computes ``M`` to normwise, not entrywise, accuracy).

    Exactly singular matrices give ``inf``.
    """
    M = np.asarray(M, dtype=float)

    def cond(A):
        s = np.linalg.svd(A, compute_uv=False)
        with np.errstate(divide="ignore"):
            return np.where(s[:, -1] > 0, s[:, 0] / np.where(s[:, -1] > 0, s[:, -1], 1.0), np.inf)

    raw = cond(M)
    dg = np.diagonal(M, axis1=1, axis2=2)
    ok = (dg > 0).all(axis=1)
    eq = np.full(M.shape[0], np.inf)
    if ok.any():
        r = 1.0 / np.sqrt(dg[ok])
        eq[ok] = cond(M[ok] * r[:, :, None] * r[:, None, :])
    return raw, eq


def solve_mass_matrix(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``M^-1 b`` for batches ``(S, d, d)``, ``(S, d)``, equilibrated by ``D = diag(M)`` first."""
    r = 1.0 / np.sqrt(np.diagonal(M, axis1=1, axis2=2))
    Ms = M * r[:, :, None] * r[:, None, :]
    return r * np.linalg.solve(Ms, (r * b)[..., None])[..., 0]


def accelerations(model: PreparedModel, q, qd, tau, check: bool = True) -> np.ndarray:
    """Forward dynamics ``qdd = M^-1 (tau - h)``, ``(S, dof)``, from a prepared model's ``M`` and ``h``.

    With ``check`` (the default) the states are validated and a singular configuration raises
    :class:`SingularConfigurationError` (see :func:`singular_reasons`) rather than returning
    NaN. The integrator calls it with ``check=False`` after checking the initial state.
    """
    if check:
        q, qd, tau = as_states(model.mechanism, q, qd, tau, source="forward dynamics")
        reasons = [f"sample {s}: {r}" for s, rs in enumerate(singular_reasons(model.mechanism, q)) for r in rs]
        if reasons:
            raise SingularConfigurationError(reasons)
    M, h = mass_matrix_and_bias(model, q, qd)
    return solve_mass_matrix(M, tau - h)


# --------------------------------------------------------------------------- controls
def prescribed_controls(model: PreparedModel, motion_of_t) -> Controls:
    """``tau(t) = ID(q*(t), qd*(t), qdd*(t))`` on the fly along an analytic motion (any ``t``,
    no interpolation), by a prepared model: the controls that should reproduce the motion.
    ``motion_of_t(t)`` returns a :class:`exo_bench.models.motion.Motion` for an array of times."""

    def controls(t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        m = motion_of_t(np.array([t]))
        return np.broadcast_to(model.inverse_dynamics(m.q, m.qd, m.qdd, check=False), q.shape)

    controls.jacobian = _no_state_dependence  # tau depends on t alone
    return controls


def _no_state_dependence(t: float, q: np.ndarray, qd: np.ndarray):
    z = np.zeros(q.shape + q.shape[-1:])
    return z, z


def rod_spring_damper(mech: Mechanism, k, c, l_rest) -> Controls:
    """Passive telescopic rods: ``F_i = -k_i (l_i - l_i*) - c_i l_i'`` on every rod, no moments
    (``k``, ``c``, ``l_rest``: one value for all rods or one per rod)."""
    n = mech.nlinks
    k, c, l_rest = (np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in (k, c, l_rest))

    def controls(t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        tau = np.zeros_like(q)
        tau[:, -n:] = -k * (q[:, -n:] - l_rest) - c * qd[:, -n:]
        return tau

    def jacobian(t: float, q: np.ndarray, qd: np.ndarray):
        """``(dtau/dq, dtau/dqd)``, ``(S, dof, dof)``: ``-k_i`` and ``-c_i`` on the rods' diagonal."""
        d = q.shape[-1]
        jq, jqd = np.zeros(q.shape + (d,)), np.zeros(q.shape + (d,))
        rods = np.arange(d - n, d)
        jq[..., rods, rods], jqd[..., rods, rods] = -k, -c
        return jq, jqd

    controls.jacobian = jacobian
    return controls


def spring_energy(mech: Mechanism, q: np.ndarray, k, l_rest) -> np.ndarray:
    """``sum_i k_i/2 (l_i - l_i*)^2`` per sample: the potential of :func:`rod_spring_damper`."""
    _, _, l = split(mech, np.atleast_2d(q))
    return 0.5 * (np.asarray(k, dtype=float) * (l - np.asarray(l_rest, dtype=float)) ** 2).sum(-1)


# --------------------------------------------------------------------------- integration
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
    status: str = "ok"  # "ok", "budget exceeded: ...", "failed: ..."
    t_reached: float = math.nan  # the latest time the right-hand side was evaluated at
    outside: int = 0  # trial stages outside the domain (l < 0): NaN, step rejected
    solution: Callable[[Any], np.ndarray] | None = field(
        default=None, repr=False
    )  # dense output (scipy OdeSolution) when asked for
    jacobian: str = "finite-difference"  # of the implicit integrators: "finite-difference" (scipy's) or "analytic"
    jacobian_columns: int = 0  # of nfev, the columns spent on scipy's finite-difference Jacobians
    # implicit integrators: the times at which the Jacobian was evaluated (in order), and of every single-column
    # right-hand-side call (stages, Newton iterations, step ends; what the stability report's Jacobian
    # comparison explains its counts with)
    jacobian_times: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    call_times: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)

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
):
    """The vectorised right-hand side ``f(t, y)`` of ``y = [q, qd]``, ``y`` of shape ``(2 dof,)`` or
    ``(2 dof, k)``, and a counter dict (``columns`` evaluated, stages ``rejected`` as outside the
    domain, the latest ``t`` reached; with ``record_times`` the ``times`` of the single-column calls and
    the ``jacobian_times`` of the multi-column ones, scipy's finite-difference Jacobians). Over budget it raises
    :class:`IntegrationBudgetExceeded`."""
    mech = model.mechanism
    d = mech.dof
    count = {
        "columns": 0,
        "jacobian_columns": 0,
        "rejected": 0,
        "t": -math.inf,
        "start": time.perf_counter(),
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
        if max_seconds is not None and time.perf_counter() - count["start"] > max_seconds:
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


#: The Jacobians an implicit integrator can use: scipy's finite differences of the vectorised
#: right-hand side (``2 dof`` columns per Jacobian), or the analytic one of :func:`make_jacobian`.
JACOBIANS = ("finite-difference", "analytic")


def make_jacobian(model: PreparedModel, controls: Controls):
    """The analytic Jacobian ``df/dy`` of the right-hand side ``f = [qd, qdd]`` of :func:`make_rhs`:
    ``[[0, I], [dqdd/dq + M^-1 dtau/dq, dqdd/dqd + M^-1 dtau/dqd]]`` with the forward-dynamics
    derivatives of ``model.derivatives`` (:mod:`exo_bench.matrix_method.derivatives`) and the controls' own
    ``controls.jacobian(t, q, qd) -> (dtau/dq, dtau/dqd)`` (:func:`prescribed_controls` and
    :func:`rod_spring_damper` have one). A ValueError when the controls have none, or when the
    derivatives are not available (the optional extra ``casadi``)."""
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
) -> Simulation:
    """Integrate ``M qdd + h = controls(t, q, qd)`` from ``(q0, qd0)`` over ``t_span``.

    ``jacobian`` (implicit integrators): ``"finite-difference"`` (scipy's, from the vectorised
    right-hand side, counted in ``nfev``) or ``"analytic"`` (:func:`make_jacobian`, kept current:
    re-evaluated after every accepted step, :mod:`exo_bench.models.implicit_integrators`).

    ``atol`` defaults to ``rtol * 1e-3`` (a state component of 1e-3 rad or mm counts as small).
    The initial state is validated and checked for a singular mass matrix (then
    :class:`SingularConfigurationError`); a failure during the integration (the budget, an
    invalid state such as a negative length, a scipy failure) is recorded in ``status``, with
    the steps accepted so far.
    """
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator: expected one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    if jacobian not in JACOBIANS:
        raise ValueError(f"jacobian: expected one of {', '.join(JACOBIANS)}, got {jacobian!r}")
    if jacobian == "analytic" and integrator not in IMPLICIT:
        raise ValueError(
            f"jacobian 'analytic': only the implicit integrators ({', '.join(IMPLICIT)}) use a "
            f"Jacobian, got {integrator!r}"
        )
    from scipy.integrate import solve_ivp

    mech = model.mechanism
    q0, qd0, _ = as_states(mech, q0, qd0, source="initial state")
    reasons = singular_reasons(mech, q0)[0]
    if reasons:
        raise SingularConfigurationError(reasons)
    atol = rtol * 1e-3 if atol is None else atol
    rhs, count = make_rhs(model, controls, max_evaluations, max_seconds, record_times=integrator in IMPLICIT)
    y0 = np.concatenate([q0[0], qd0[0]])
    steps_t, steps_y = [t_span[0]], [y0]
    t0 = time.perf_counter()
    status, sol = "ok", None
    kw = {} if first_step is None else {"first_step": first_step}
    if jacobian == "analytic":
        analytic_jac = make_jacobian(model, controls)

        def jac(t: float, y: np.ndarray) -> np.ndarray:
            count["jacobian_times"].append(t)
            return analytic_jac(t, y)

        kw["jac"] = jac
    method = CURRENT_JACOBIAN[integrator] if jacobian == "analytic" else integrator
    try:
        r = solve_ivp(rhs, t_span, y0, method=method, rtol=rtol, atol=atol, vectorized=True, dense_output=dense, **kw)
        steps_t, steps_y = list(r.t), list(r.y.T)
        njev, nlu = int(r.njev), int(r.nlu)
        sol = r.sol
        if r.status != 0:
            status = f"failed: {r.message}"
    except IntegrationBudgetExceeded as e:
        status, njev, nlu = f"budget exceeded: {e.skip_reason}", 0, 0
    except Exception as e:  # noqa: BLE001 - a method over its budget or raising: record, do not crash
        skip = getattr(e, "skip_reason", None)
        status = f"skipped: {skip}" if skip else "failed: " + traceback.format_exception_only(type(e), e)[-1].strip()
        njev, nlu = 0, 0
    seconds = time.perf_counter() - t0
    return Simulation(
        integrator,
        rtol,
        atol,
        np.asarray(steps_t),
        np.asarray(steps_y),
        count["columns"],
        njev,
        nlu,
        seconds,
        status,
        float(count["t"]),
        count["rejected"],
        sol,
        jacobian,
        count["jacobian_columns"],
        np.asarray(count["jacobian_times"]),
        np.asarray(count["times"]),
    )
