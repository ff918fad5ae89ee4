"""Forward dynamics: accelerations from a method's mass matrix and bias forces, and their integration.

The equations of motion of every method have the form ``M(q) qdd + h(q, qd) = tau``. Forward
dynamics solves them for ``qdd``:

Every function takes a prepared model (:func:`exo_bench.prepare`, :mod:`exo_bench.models.runtime.prepared`):

* **Pinocchio** exposes ``M`` (CRBA) and ``h`` (``nonLinearEffects``) directly. Its ABA would be
  faster, but it refuses the mimic joints of the generated URDF, so the suite uses CRBA and a
  solve.
* **Any method** ``tau = ID(q, qd, qdd)`` gives them exactly, because inverse dynamics is
  linear in ``qdd``: ``h = ID(q, qd, 0)`` and ``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)``
  (:func:`exo_bench.models.runtime.prepared.terms_from_inverse_dynamics`, one batched call per evaluation); a
  prepared model uses its own terms where it has them (``native_terms``).

**Singular configurations.** ``M = J^T (mu (x) I) J``, where ``J`` maps ``qd`` to the rod
vectors' rates ``d/dt(s_i l_i u_i)`` (per link the columns ``l_i du_i/dphi_i``,
``l_i du_i/dpsi_i``, ``u_i``) and ``mu`` is the mass coupling of eq. (6), the mass distribution
matrix (:func:`exo_bench.models.mechanism.aggregates.coupling`). ``M`` is singular exactly when ``mu`` is singular or
a link's columns are dependent: a rod of length zero (its angles move no mass) or, in 3D, a vertical rod
(``cos psi_i = 0``: the azimuth column ``l_i cos psi_i (-sin phi_i, cos phi_i, 0)`` vanishes).
Inverse dynamics is still defined there; forward dynamics is not, and
:func:`accelerations` raises :class:`~exo_bench.models.mechanism.singularity.SingularConfigurationError` naming the link instead of
returning NaN or garbage. :func:`~exo_bench.models.mechanism.singularity.singular_reasons` does the detection, exactly (no threshold on
a condition number), and :func:`condition_numbers` measures how close to singular ``M`` is. Near
those states every method refuses alike where the error model cannot vouch for the answer: one
conditioning test with its bound, :mod:`exo_bench.models.runtime.conditioning`.

**Integration** (:func:`~exo_bench.models.simulation.forward_dynamics.simulate`, in :mod:`exo_bench.models.simulation.forward_dynamics`) steps scipy's integrators on ``y = [q, qd]``, with
explicit (RK45, DOP853) or implicit (Radau, BDF) integrators. The right-hand side is vectorised,
so the implicit integrators' finite-difference Jacobian costs one batched call per column block;
``jacobian="analytic"`` gives them :func:`make_jacobian` instead (the forward-dynamics derivatives
of ``model.derivatives`` and the controls' ``jacobian``), which costs no right-hand-side evaluation
and is therefore re-evaluated after every accepted step (:mod:`exo_bench.models.simulation.forward_dynamics`).

**Integration**: :func:`simulate` with its checked arguments, right-hand side (with
external forces), implicit integrators, budget and result.

:func:`simulate` integrates ``M(q) qdd + h(q, qd) = controls(t, q, qd)`` (the accelerations of
:mod:`exo_bench.models.simulation.forward_dynamics`) with one of scipy's ``OdeSolver`` classes, stepped here
rather than through ``solve_ivp``, so that a run stopped by its budget keeps the steps it accepted.

**Every argument is validated before any work** (:func:`check_simulate_arguments`): a
``ValueError`` names the argument, the expected and the actual value. **There is always a budget**:
at most ``max_evaluations`` right-hand-side evaluations (:data:`DEFAULT_MAX_EVALUATIONS` when not
given) and, optionally, ``max_seconds`` read from ``clock`` (``time.perf_counter`` unless another is
injected, as tests do). Each step evaluates the right-hand side at least once, so the loop ends.

**The arguments**, checked before any work. Each check raises ``ValueError("simulate: argument 'name': expected ..., got ...")``. What they rule
out is every combination that made ``simulate`` hang or answer nonsense: a time span that is not two
finite increasing numbers (``(0, nan)`` never ends), ``rtol`` of 0, NaN or below scipy's floor (scipy
raises it to 100 eps with a warning, or loops on NaN), ``atol`` not finite and positive (an error
scale of 0 or NaN), budgets that are not positive (``max_seconds=-1``), strings where numbers belong
(``"1"``), and a ``first_step`` outside the span. ``max_evaluations=None`` is the default budget
:data:`DEFAULT_MAX_EVALUATIONS`: no run is without one.

**scipy's implicit integrators with an analytic Jacobian kept current.** scipy's ``Radau`` and ``BDF`` are tuned for a Jacobian estimated by finite differences, which costs
``2 dof`` right-hand-side evaluations (vectorised: one call of ``2 dof`` columns) each time. They
therefore hold a Jacobian as long as they can:

* ``Radau`` re-evaluates it only after a step whose simplified Newton iteration needed more than 2
  iterations with a last contraction rate above 1e-3, or after a Newton failure;
* ``BDF`` only after a Newton failure.

Between those events each Newton iteration works with a Jacobian from an older state: it converges
more slowly (more stage evaluations per step), and Radau's error estimate, which passes through
``(3.638/h I - J)^-1``, differs, so the steps differ too. The stability report measured this: at
rtol 1e-12 on the planar gait, an analytic Jacobian under scipy's rule held a stale Jacobian from
0.18 to 0.27 s and took 4% *more* evaluations than finite differences.

An analytic Jacobian (:func:`make_jacobian`) costs no right-hand-side
evaluation, so the rule that fits it is the opposite one: re-evaluate it at the new state after
every accepted step (one Jacobian and, as after most step-size changes anyway, one new LU per step).
:class:`RadauCurrentJacobian` and :class:`BDFCurrentJacobian` do exactly that and nothing else: they
run scipy's own step (``_step_impl``, the extension point of ``scipy.integrate.OdeSolver``) and then
replace the Jacobian held and drop the factorisation built from the old one. ``njev`` counts every
evaluation, the refreshes included. :data:`CURRENT_JACOBIAN` maps the integrator names onto them;
:func:`simulate` uses them for ``jacobian="analytic"``.

The attributes replaced (``J``, ``current_jac``, ``LU_real``/``LU_complex`` of Radau, ``J``, ``LU`` of
BDF) are those of scipy 1.11-1.17; ``tests/test_analytic_jacobian.py`` fails if a scipy release
renames them (the count of Jacobians per step).

**The right-hand side with external forces** ``f_ext(t, q, qd)`` (issue 37): the controls plus
``Q(q, f_ext)`` (:class:`ControlsWithForces`), with the Jacobian of the sum for ``jacobian="analytic"``
(:class:`ControlsWithForcesJacobian`); the forces themselves, their checks and ``Q`` are
:mod:`exo_bench.models.runtime.external_forces`'.
"""

from __future__ import annotations

import math
import numbers
import time
import traceback
from array import array
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.runtime.conditioning import check_finite
from exo_bench.models.runtime.external_forces import check_f_ext, dQ_dq, generalized_forces, refuse_overflow
from exo_bench.models.runtime.prepared import PreparedModel, terms_from_inverse_dynamics
from exo_bench.models.states.states import as_states, split
from numpy.typing import ArrayLike
from scipy.integrate import BDF, Radau

if TYPE_CHECKING:
    from exo_bench.models.gait.motion import Motion  # only named in annotations

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
    dynamics (:func:`exo_bench.models.runtime.prepared.terms_from_inverse_dynamics`, one batched call).
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
    :class:`~exo_bench.models.mechanism.singularity.SingularConfigurationError` (see :func:`~exo_bench.models.mechanism.singularity.singular_reasons`), one beyond the conditioning
    bound :class:`exo_bench.models.runtime.conditioning.NumericallySingularError`, rather than returning
    NaN or an answer the error model cannot vouch for. The integrator calls it with ``check=False``
    after checking the initial state.
    """
    if check:
        q, qd, tau = as_states(model.mechanism, q, qd, tau, source="forward dynamics")
        model.check_regular(q)  # exact singularities, then the conditioning test every method shares
    M, h = mass_matrix_and_bias(model, q, qd)
    qdd = solve_mass_matrix(M, tau - h)
    if check:
        check_finite(model.mechanism, qdd)
    return qdd


# --------------------------------------------------------------------------- controls
#: ``controls.jacobian(t, q, qd) -> (dtau/dq, dtau/dqd)``, each ``(S, dof, dof)``.
ControlsJacobian = Callable[[float, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True, eq=False)
class PrescribedControls:
    """``tau(t) = ID(q*(t), qd*(t), qdd*(t))`` on the fly along an analytic motion (any ``t``,
    no interpolation), by a prepared model: the controls that should reproduce the motion.
    ``motion_of_t(t)`` returns a :class:`exo_bench.models.gait.motion.Motion` for an array of times."""

    model: PreparedModel
    motion_of_t: Callable[[np.ndarray], Motion]

    def __call__(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        m = self.motion_of_t(np.array([t]))
        return np.broadcast_to(self.model.inverse_dynamics(m.q, m.qd, m.qdd, check=False), q.shape)

    def jacobian(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Zero: tau depends on t alone."""
        z = np.zeros(q.shape + q.shape[-1:])
        return z, z


def prescribed_controls(model: PreparedModel, motion_of_t: Callable[[np.ndarray], Motion]) -> PrescribedControls:
    """:class:`PrescribedControls` of a prepared model along ``motion_of_t``."""
    return PrescribedControls(model, motion_of_t)


@dataclass(frozen=True, eq=False)
class RodSpringDamper:
    """Passive telescopic rods: ``F_i = -k_i (l_i - l_i*) - c_i l_i'`` on every rod, no moments;
    ``k``, ``c``, ``l_rest`` are ``(n,)``."""

    n: int
    k: np.ndarray
    c: np.ndarray
    l_rest: np.ndarray

    def __call__(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        n = self.n
        tau = np.zeros_like(q)
        tau[:, -n:] = -self.k * (q[:, -n:] - self.l_rest) - self.c * qd[:, -n:]
        return tau

    def jacobian(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(dtau/dq, dtau/dqd)``, ``(S, dof, dof)``: ``-k_i`` and ``-c_i`` on the rods' diagonal."""
        d = q.shape[-1]
        jq, jqd = np.zeros(q.shape + (d,)), np.zeros(q.shape + (d,))
        rods = np.arange(d - self.n, d)
        jq[..., rods, rods], jqd[..., rods, rods] = -self.k, -self.c
        return jq, jqd


def rod_spring_damper(mech: Mechanism, k: ArrayLike, c: ArrayLike, l_rest: ArrayLike) -> RodSpringDamper:
    """:class:`RodSpringDamper` on every rod of ``mech`` (``k``, ``c``, ``l_rest``: one value for all
    rods or one per rod)."""
    n = mech.nlinks
    k_, c_, l_rest_ = (np.broadcast_to(np.asarray(x, dtype=float), (n,)) for x in (k, c, l_rest))
    return RodSpringDamper(n, k_, c_, l_rest_)


def spring_energy(mech: Mechanism, q: np.ndarray, k, l_rest) -> np.ndarray:
    """``sum_i k_i/2 (l_i - l_i*)^2`` per sample: the potential of :func:`rod_spring_damper`."""
    _, _, l = split(mech, np.atleast_2d(q))
    return 0.5 * (np.asarray(k, dtype=float) * (l - np.asarray(l_rest, dtype=float)) ** 2).sum(-1)


class ControlsWithForces:
    """``controls(t, q, qd) + Q(q, f_ext(t, q, qd))``: what ``simulate`` integrates with ``f_ext``
    (ground contact, interaction forces that depend on the state). ``f_ext`` is called as the controls
    are, with ``q, qd`` of shape ``(k, dof)``, and returns forces ``(k, links, 3, dim)`` (``(links, 3,
    dim)`` is taken for ``k = 1``); a force that is not finite is a ValueError naming the link and the
    point."""

    def __init__(self, model: Any, controls: Callable[..., Any], f_ext: Callable[..., Any]):
        self.model, self.controls, self.f_ext = model, controls, f_ext

    def __call__(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        f = self.forces(t, q, qd)
        Q = self.model._external_forces(q, f)
        refuse_overflow(self.model.mechanism, f"simulate at t = {t:.6g} s", f, Q, "Q")
        return self.controls(t, q, qd) + Q

    def forces(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """``f_ext(t, q, qd)``, checked, ``(k, links, 3, dim)``."""
        f = self.f_ext(t, q, qd)  # read by check_f_ext: real numbers only, as the calls read f_ext
        mech = self.model.mechanism
        if q.shape[0] == 1 and _shape(f) == (mech.nlinks, 3, mech.dim):
            f = np.asarray(f)[None]
        return check_f_ext(mech, f, q.shape, True, f"simulate at t = {t:.6g} s")


def _shape(a: Any) -> tuple | None:
    try:
        return np.shape(a)
    except ValueError:  # ragged: check_f_ext names it
        return None


class ControlsWithForcesJacobian(ControlsWithForces):
    """:class:`ControlsWithForces` whose controls and ``f_ext`` both have a ``jacobian(t, q, qd)``, with
    the Jacobian of the sum for ``simulate(jacobian="analytic")``: ``dQ/dq = dQ/dq|_f + J^T df/dq`` (the
    geometry, :func:`dQ_dq`, and the forces' own change, ``Q`` being linear in ``f``), ``dQ/dqd = J^T
    df/dqd``. ``f_ext.jacobian`` returns ``(df/dq, df/dqd)``, each ``(k, links, 3, dim, dof)``."""

    def jacobian(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mech = self.model.mechanism
        cq, cqd = self.controls.jacobian(t, q, qd)  # type: ignore[attr-defined]  # checked by with_external_forces
        want = (q.shape[0], mech.nlinks, 3, mech.dim, mech.dof)
        fq, fqd = (np.broadcast_to(np.asarray(a, dtype=float), want) for a in self.f_ext.jacobian(t, q, qd))  # type: ignore[attr-defined]
        return cq + dQ_dq(mech, q, self.forces(t, q, qd)) + _through(mech, q, fq), cqd + _through(mech, q, fqd)


def _through(mech: Mechanism, q: np.ndarray, G: np.ndarray) -> np.ndarray:
    """``J^T G``, ``(k, dof, dof)``: column ``j`` the generalised forces of the forces' derivative ``G[..., j]``."""
    k, d = q.shape
    cols = np.moveaxis(G, -1, 1).reshape(k * d, *G.shape[1:-1])
    return generalized_forces(mech, np.repeat(q, d, axis=0), cols).reshape(k, d, d).transpose(0, 2, 1)


def with_external_forces(model: Any, controls: Callable[..., Any], f_ext: Any, jacobian: str) -> ControlsWithForces:
    """``simulate``'s controls with the external forces ``f_ext(t, q, qd)`` added (:class:`ControlsWithForces`),
    after checking that ``f_ext`` is a function. The analytic Jacobian needs ``f_ext.jacobian(t, q, qd) ->
    (df/dq, df/dqd)`` (:class:`ControlsWithForcesJacobian`, when the controls have theirs too); without it
    it is refused by name."""
    if not callable(f_ext):
        raise ValueError(
            f"simulate: field 'f_ext': expected a function (t, q, qd) -> forces (samples, links, 3, dim) in "
            f"newtons, got {type(f_ext).__name__}"
        )
    if jacobian == "analytic" and not callable(getattr(f_ext, "jacobian", None)):
        raise ValueError(
            "simulate: field 'jacobian': expected 'finite-difference' with f_ext (the analytic Jacobian has no "
            "derivative of f_ext(t, q, qd): give f_ext a jacobian(t, q, qd) -> (df/dq, df/dqd) attribute, each "
            "(samples, links, 3, dim, dof)), got 'analytic'"
        )
    if jacobian == "analytic" and callable(getattr(controls, "jacobian", None)):
        return ControlsWithForcesJacobian(model, controls, f_ext)
    return ControlsWithForces(model, controls, f_ext)


class RadauCurrentJacobian(Radau):
    """scipy's Radau IIA (order 5), with the Jacobian re-evaluated at the new state after every
    accepted step (scipy holds it until a Newton iteration converges slowly or fails)."""

    def _step_impl(self):
        accepted, message = super()._step_impl()
        if accepted and not self.current_jac:
            self.J = self.jac(self.t, self.y, self.f)
            self.current_jac = True
            self.LU_real = self.LU_complex = None
        return accepted, message


class BDFCurrentJacobian(BDF):
    """scipy's variable-order BDF (NDF), with the Jacobian re-evaluated at the new state after every
    accepted step (scipy holds it until a Newton iteration fails)."""

    def _step_impl(self):
        accepted, message = super()._step_impl()
        if accepted:
            self.J = self.jac(self.t, self.y)
            self.LU = None
        return accepted, message


#: The ``solve_ivp`` method for each implicit integrator when the Jacobian is analytic.
CURRENT_JACOBIAN = {"Radau": RadauCurrentJacobian, "BDF": BDFCurrentJacobian}

#: The Jacobians an implicit integrator can use: scipy's finite differences of the vectorised
#: right-hand side (``2 dof`` columns per Jacobian), or the analytic one of
#: :func:`exo_bench.models.simulation.forward_dynamics.make_jacobian`.
JACOBIANS = ("finite-difference", "analytic")
#: The smallest rtol: 100 machine epsilons, scipy's own floor (it raises smaller values to it).
RTOL_FLOOR = 100 * float(np.finfo(float).eps)
#: The budget of a run that states none, in right-hand-side evaluations (columns): 90 times the
#: largest run of the stability study (11,354 evaluations), seconds to minutes of work.
DEFAULT_MAX_EVALUATIONS = 1_000_000


@dataclass(frozen=True)
class SimulateArguments:
    """The checked arguments, as plain floats and ints, with the defaults filled in."""

    t_span: tuple[float, float]
    rtol: float
    atol: float
    max_evaluations: int
    max_seconds: float | None
    first_step: float | None


def _bad(name: str, expected: str, got: Any) -> ValueError:
    return ValueError(f"simulate: argument '{name}': expected {expected}, got {got!r}")


def _is_real(x: Any) -> bool:
    """A real number that is not a bool (nor a string, a Decimal, an array...)."""
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _real(name: str, x: Any, expected: str, ok: Callable[[float], bool]) -> float:
    if not _is_real(x) or not ok(float(x)):
        raise _bad(name, expected, x)
    return float(x)


def _positive(name: str, x: Any) -> float:
    return _real(name, x, "a finite number > 0", lambda v: math.isfinite(v) and v > 0)


def check_budget(max_evaluations: Any, max_seconds: Any, allow_none: bool = False) -> tuple[int | None, float | None]:
    """``(max_evaluations, max_seconds)`` checked: an integer >= 1 and a finite number > 0; ``None``
    is :data:`DEFAULT_MAX_EVALUATIONS` (``allow_none``: no limit) and no wall-time limit."""
    if max_evaluations is None:
        n = None if allow_none else DEFAULT_MAX_EVALUATIONS
    elif isinstance(max_evaluations, numbers.Integral) and not isinstance(max_evaluations, (bool, np.bool_)):
        n = int(max_evaluations)
        if n < 1:
            raise _bad("max_evaluations", "an integer >= 1 (or None for the default budget)", max_evaluations)
    else:
        raise _bad("max_evaluations", "an integer >= 1 (or None for the default budget)", max_evaluations)
    seconds = None if max_seconds is None else _positive("max_seconds", max_seconds)
    return n, seconds


def _t_span(t_span: Any) -> tuple[float, float]:
    expected = "two finite times (s), increasing: (t0, t1) with t0 < t1"
    if isinstance(t_span, (str, bytes)) or not hasattr(t_span, "__len__") or len(t_span) != 2:
        raise _bad("t_span", expected, t_span)
    a, b = t_span[0], t_span[1]
    if not (_is_real(a) and _is_real(b)) or not (math.isfinite(a) and math.isfinite(b) and float(a) < float(b)):
        raise _bad("t_span", expected, t_span)
    return float(a), float(b)


def check_simulate_arguments(
    model: Any,
    t_span: Any,
    controls: Any,
    integrator: Any,
    rtol: Any,
    atol: Any,
    max_evaluations: Any,
    max_seconds: Any,
    dense: Any,
    first_step: Any,
    jacobian: Any,
    clock: Any,
) -> SimulateArguments:
    """Every argument of ``simulate`` but the states (those are checked by
    :func:`exo_bench.models.states.states.as_states`), checked; the defaults filled in."""
    if not isinstance(model, PreparedModel):
        raise _bad("model", "a prepared model (exo_bench.prepare(mechanism, method))", type(model).__name__)
    if integrator not in INTEGRATORS:
        raise _bad("integrator", f"one of {', '.join(INTEGRATORS)}", integrator)
    if jacobian not in JACOBIANS:
        raise _bad("jacobian", f"one of {', '.join(JACOBIANS)}", jacobian)
    if jacobian == "analytic" and integrator not in IMPLICIT:
        raise _bad(
            "jacobian",
            f"'finite-difference' with {integrator} (only the implicit integrators, {', '.join(IMPLICIT)}, use one)",
            jacobian,
        )
    span = _t_span(t_span)
    if not callable(controls):
        raise _bad("controls", "a function (t, q, qd) -> tau", controls)
    if not callable(clock):
        raise _bad("clock", "a function () -> seconds", clock)
    if not isinstance(dense, (bool, np.bool_)):
        raise _bad("dense", "True or False", dense)
    rt = _real("rtol", rtol, f"a number >= {RTOL_FLOOR:.4g} (100 eps) and < 1", lambda v: RTOL_FLOOR <= v < 1.0)
    at = rt * 1e-3 if atol is None else _positive("atol", atol)
    n, seconds = check_budget(max_evaluations, max_seconds)
    assert n is not None
    first = None
    if first_step is not None:
        width = span[1] - span[0]
        first = _real(
            "first_step", first_step, f"None or a number in (0, {width:g}] (the span)", lambda v: 0 < v <= width
        )
    return SimulateArguments(span, rt, at, n, seconds, first)


if TYPE_CHECKING:
    from exo_bench.models.runtime.prepared import PreparedModel

Clock = Callable[[], float]


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
    derivatives of ``model.derivatives`` (:mod:`exo_bench.models.derivatives`: the analytic derivatives of
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
      re-evaluated after every accepted step, :mod:`exo_bench.models.simulation.forward_dynamics`);
    * ``first_step``: ``None`` (scipy chooses) or in ``(0, t_span[1] - t_span[0]]``; ``dense``: a bool.
    * ``f_ext``: external forces at the point masses, ``f_ext(t, q, qd) -> (samples, links, 3, dim)``
      called as the controls are (ground contact, interaction, loads): with it ``M qdd + h = controls + Q(q,
      f_ext)`` (:class:`exo_bench.models.simulation.forward_dynamics.ControlsWithForces`, docs/external-forces.md);
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
