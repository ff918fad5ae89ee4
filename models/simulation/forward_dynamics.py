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

**Integration** (:func:`~exo_bench.models.simulation.simulate.simulate`, in :mod:`exo_bench.models.simulation.simulate`) steps scipy's integrators on ``y = [q, qd]``, with
explicit (RK45, DOP853) or implicit (Radau, BDF) integrators. The right-hand side is vectorised,
so the implicit integrators' finite-difference Jacobian costs one batched call per column block;
``jacobian="analytic"`` gives them :func:`make_jacobian` instead (the forward-dynamics derivatives
of ``model.derivatives`` and the controls' ``jacobian``), which costs no right-hand-side evaluation
and is therefore re-evaluated after every accepted step (:mod:`exo_bench.models.simulation.simulate`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from exo_bench.models.runtime.conditioning import check_finite
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states, split
from exo_bench.models.runtime.prepared import PreparedModel
from exo_bench.models.runtime.prepared import terms_from_inverse_dynamics

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
