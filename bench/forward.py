"""Forward-dynamics experiments of the stability report: round trip, energy drift, stiffness, work.

Everything integrates ``M(q) qdd + h(q, qd) = tau`` with :func:`models.forward_dynamics.simulate`
(scipy's ``solve_ivp``: RK45, DOP853 explicit; Radau, BDF implicit with a finite-difference
Jacobian that scipy estimates from the vectorised right-hand side).

* **Round trip** (:func:`round_trip`): the controls that inverse dynamics computes along a
  prescribed analytic motion, ``tau(t) = ID(q*(t), qd*(t), qdd*(t))`` evaluated on the fly, must
  reproduce the motion. Pass criterion (:data:`ROUND_TRIP_RULE`): the deviation from ``q*`` is at
  most twice the integrator's own global error, estimated without ``q*`` by a second run at a
  100x tighter tolerance, plus a round-off floor. The first-order worst case, propagated with the
  linearised flow ``Phi`` (:func:`variational`), is reported beside it.
* **Conservative case** (:func:`energy_drift`): no controls, passive springs in the rods; the
  drift of ``T + Pi + V_spring`` must stay below the first-order bound from the tolerance
  (:func:`energy_bound`): energy is a first integral, so local errors are not amplified.
* **Stiff variants** (:func:`stiff_run`): critically damped stiff springs in the rods, or tiny
  masses; explicit integrators' step counts grow like ``sqrt(k/m)``, implicit ones do not.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from exo_bench.bench.methods import PreparedSet
from exo_bench.bench.study import UnusableMethodWarning, one_line
from exo_bench.models import forward_dynamics as fd
from exo_bench.models.kinematics import kinetic_energy, total_energy
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.motion import Motion, planar_gait, smooth_random_motion
from exo_bench.models.presets import chain, exo5, random_tree

EPS = np.finfo(float).eps

#: atol = ATOL_FACTOR * rtol: a state component of 1e-2 (rad, m, rad/s, m/s) counts as small.
ATOL_FACTOR = 1e-2
#: The second run of a round trip uses rtol / TIGHTER to estimate the first run's global error.
TIGHTER = 100.0

ROUND_TRIP_RULE = (
    "max_t |q(t) - q*(t)| <= 2 E + F, where E = max_t |q_rtol(t) - q_rtol/100(t)| is the integrator's own "
    "global error, estimated from a second run at a 100x tighter tolerance that never looks at q*, and "
    "F = N_steps * G(H) * eps * max|y| is the round-off floor (every step may add a few eps * |y|, and a "
    "perturbation grows by at most G(H) = max_t ||Phi_q(t)||_inf over the horizon H). Why 2 E: if the "
    "tighter run's deviation is at most half the first run's (any convergent method whose error follows the "
    "tolerance, here 100x tighter), then err <= E + err/2. If the controls did not reproduce the motion, "
    "q* would not solve the ODE and the deviation would not shrink with the tolerance: the rule fails.")


# ----------------------------------------------------------------------------- helpers
def _models(models: PreparedSet | None) -> PreparedSet:
    """The run's prepared models, or this process's default set (default options)."""
    return _DEFAULT_MODELS if models is None else models


_DEFAULT_MODELS = PreparedSet()


def _state0(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    return motion.q[:1], motion.qd[:1]


# ----------------------------------------------------------------------------- round trip
@dataclass(frozen=True, eq=False)
class RoundTripCase:
    name: str
    mechanism: Mechanism
    motion_of_t: Callable[[np.ndarray], Motion]
    horizon: float
    description: str


def round_trip_cases(full: bool = False) -> list[RoundTripCase]:
    """The prescribed motions of the round trip.

    * the planar gait (eq. 26 in the sagittal plane) of the five-link exoskeleton over 0.3 s: the
      stance leg and trunk stand upright, an inverted multi-link pendulum, so open-loop
      perturbations grow about 10x per 0.05 s; 0.3 s keeps the growth G near 1e4;
    * smooth random motions of seeded random trees (2D and 3D) over 1 s.
    """
    e2 = exo5(2)
    t2, t3 = random_tree(4, 2, 5), random_tree(4, 3, 5)
    cases = [
        RoundTripCase("exo5-2d planar gait", e2, lambda t: planar_gait(e2, t), 0.3,
                      "eq. (26) in the sagittal plane, T = 1.1 s, first 0.3 s"),
        RoundTripCase("tree4-2d random motion", t2, lambda t: smooth_random_motion(t2, t, 3), 1.0,
                      "smooth random motion (seed 3) of random_tree(4, 2, 5), 1 s"),
        RoundTripCase("tree4-3d random motion", t3, lambda t: smooth_random_motion(t3, t, 3), 1.0,
                      "smooth random motion (seed 3) of random_tree(4, 3, 5), 1 s"),
    ]
    if full:
        t5 = random_tree(6, 3, 11)
        cases.append(RoundTripCase("tree6-3d random motion", t5, lambda t: smooth_random_motion(t5, t, 4), 1.0,
                                   "smooth random motion (seed 4) of random_tree(6, 3, 11), 1 s"))
    return cases


@dataclass
class Variational:
    """The linearised flow ``Phi(t) = dy(t)/dy(0)`` along a controlled trajectory, from ``2 dof``
    perturbed copies integrated together with the nominal one (forward differences, ``delta``)."""

    dof: int
    delta: float
    solution: object
    horizon: float

    def phi(self, t) -> np.ndarray:
        """``(N, m, m)`` for an array of times (``m = 2 dof``)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        m = 2 * self.dof
        Z = self.solution(t).reshape(m, m + 1, -1)          # (state, copy, time)
        return np.moveaxis((Z[:, 1:] - Z[:, :1]) / self.delta, -1, 0)

    def growth(self, t) -> np.ndarray:
        """``||Phi_q(t)||_inf``: how much a state perturbation at 0 can move q at ``t``."""
        return np.abs(self.phi(t)[:, :self.dof]).sum(-1).max(-1)

    def max_growth(self, samples: int = 41) -> float:
        return float(self.growth(np.linspace(0, self.horizon, samples)).max())


def variational(mech: Mechanism, controls: fd.Controls, q0, qd0, horizon: float, method: str = "pinocchio",
                delta: float = 1e-7, rtol: float = 1e-12, models: PreparedSet | None = None) -> Variational:
    """Integrate the nominal state and ``2 dof`` copies perturbed by ``delta`` in one vectorised
    ODE (DOP853, tight tolerance): each copy is one column of the vectorised right-hand side."""
    from scipy.integrate import solve_ivp

    d = mech.dof
    m = 2 * d
    rhs, _ = fd.make_rhs(_models(models)(mech, method), controls)
    y0 = np.concatenate([np.asarray(q0, float).ravel(), np.asarray(qd0, float).ravel()])
    Z0 = y0[:, None] + delta * np.hstack([np.zeros((m, 1)), np.eye(m)])
    sol = solve_ivp(lambda t, z: rhs(t, z.reshape(m, m + 1)).ravel(), (0.0, horizon), Z0.ravel(),
                    method="DOP853", rtol=rtol, atol=rtol * 1e-2, dense_output=True)
    if sol.status != 0:
        raise RuntimeError(f"variational equations of {mech.name}: {sol.message}")
    return Variational(d, delta, sol.sol, horizon)


def a_priori_bound(var: Variational, sim: fd.Simulation, checkpoints: int = 12) -> float:
    """First-order worst case of the global error in q, ``max_j sum_{k<=j} |Phi(t_j) Phi(t_k)^-1|_q
    sqrt(m) (atol + rtol max(|y_k-1|, |y_k|))``: every accepted step's local error passes scipy's RMS
    test, so each component is below ``sqrt(m)`` times its scale, and is propagated by the
    linearised flow. Evaluated at ``checkpoints`` step times (the sum is O(N^2) in the steps)."""
    if sim.steps == 0:
        return 0.0
    d, m = var.dof, 2 * var.dof
    P = var.phi(sim.t)                                              # (N, m, m)
    inv = np.linalg.inv(P)
    sc = sim.atol + sim.rtol * np.maximum(np.abs(sim.y[:-1]), np.abs(sim.y[1:]))   # (N-1, m), step k -> k-1
    w = math.sqrt(m) * sc
    N = len(sim.t)
    best = 0.0
    for j in np.unique(np.linspace(1, N - 1, checkpoints).round().astype(int)):
        A = np.abs(np.einsum("ab,kbc->kac", P[j, :d], inv[1:j + 1]))   # (j, d, m): Phi(t_j, t_k), q rows
        best = max(best, float(np.einsum("kac,kc->a", A, w[:j]).max()))
    return best


@dataclass
class RoundTrip:
    case: str
    method: str
    integrator: str
    rtol: float
    sim: fd.Simulation
    error: float = math.nan           # max over accepted steps of |q - q*| (rad or m)
    estimate: float = math.nan        # E: max |q_rtol - q_tighter| at the same times
    floor: float = math.nan           # F: round-off floor
    bound: float = math.nan           # a priori first-order worst case
    growth: float = math.nan          # G(H)
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


def round_trip_run(case: RoundTripCase, integrator: str, rtol: float, method: str = "pinocchio",
                   control_method: str = "pinocchio", max_seconds: float | None = None,
                   controls: fd.Controls | None = None, models: PreparedSet | None = None) -> fd.Simulation:
    """One integration of the round trip (dense output, so that it can serve as the tighter run
    of another): the forward dynamics of ``method`` driven by ``control_method``'s inverse
    dynamics along the case's motion (or by ``controls`` when given), from the motion's initial
    state."""
    mech = case.mechanism
    models = _models(models)
    ctrl = controls or fd.prescribed_controls(models(mech, control_method), case.motion_of_t)
    q0, qd0 = _state0(case.motion_of_t(np.array([0.0])))
    return fd.simulate(models(mech, method), q0, qd0, (0.0, case.horizon), ctrl, integrator, rtol, ATOL_FACTOR * rtol,
                       max_seconds=max_seconds, dense=True)


def round_trip(case: RoundTripCase, integrator: str, rtol: float, method: str = "pinocchio",
               control_method: str = "pinocchio", var: Variational | None = None,
               sim: fd.Simulation | None = None, tighter: fd.Simulation | None = None,
               estimate: bool = True, max_seconds: float | None = None,
               controls: fd.Controls | None = None, models: PreparedSet | None = None) -> RoundTrip:
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
        tighter = round_trip_run(case, integrator, rtol / TIGHTER, method, control_method, max_seconds, controls,
                                 models)
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


# ----------------------------------------------------------------------------- conservative case
@dataclass(frozen=True, eq=False)
class SpringCase:
    name: str
    mechanism: Mechanism
    q0: np.ndarray
    qd0: np.ndarray
    k: float
    c: np.ndarray | float
    l_rest: np.ndarray
    horizon: float
    description: str

    @property
    def controls(self) -> fd.Controls:
        return fd.rod_spring_damper(self.mechanism, self.k, self.c, self.l_rest)

    def energy(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """``T + Pi + V_spring`` per sample."""
        return total_energy(self.mechanism, q, qd) + fd.spring_energy(self.mechanism, q, self.k, self.l_rest)


def conservative_cases() -> list[SpringCase]:
    """Passive mechanisms (no actuators) with springs in the rods, no damping.

    Without a restoring force the telescopes of a free mechanism collapse (``l -> 0``, where M is
    singular) or extend without bound, so the rods carry springs ``F = -k (l - l*)`` at a moderate
    ``k`` (rod modes of 10-60 rad/s, not stiff); their energy ``k/2 (l - l*)^2`` joins ``T + Pi``.
    """
    e2 = exo5(2)
    g = planar_gait(e2, np.array([0.0]))
    t3 = random_tree(4, 3, 5)
    rng = np.random.default_rng(7)
    n = t3.nlinks
    q3 = np.concatenate([rng.uniform(-math.pi, math.pi, n), rng.uniform(-0.8, 0.8, n), rng.uniform(0.4, 1.0, n)])
    qd3 = rng.uniform(-1.0, 1.0, 3 * n) * np.r_[np.ones(2 * n), 0.1 * np.ones(n)]
    return [
        SpringCase("exo5-2d passive fall", e2, g.q[0], g.qd[0], 2e3, 0.0, g.q[0, -5:], 0.5,
                   "the five-link exoskeleton released from the gait's initial state, rods on springs "
                   "k = 2e3 N/m at their initial length, 0.5 s"),
        SpringCase("tree4-3d passive swing", t3, q3, qd3, 2e3, 0.0, q3[-n:], 1.0,
                   "random_tree(4, 3, 5) from a seeded random state, rods on springs k = 2e3 N/m, 1 s"),
    ]


def energy_gradient(case: SpringCase, y: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """``dE/dy (N, m)`` by central differences (one batched energy call)."""
    N, m = y.shape
    d = m // 2
    steps = h * np.maximum(1.0, np.abs(y))                             # (N, m)
    Y = np.repeat(y[:, None, :], 2 * m, axis=1)                        # (N, 2m, m)
    idx = np.arange(m)
    Y[:, idx, idx] += steps
    Y[:, m + idx, idx] -= steps
    E = case.energy(Y[..., :d].reshape(-1, d), Y[..., d:].reshape(-1, d)).reshape(N, 2 * m)
    return (E[:, :m] - E[:, m:]) / (2 * steps)


def energy_bound(case: SpringCase, sim: fd.Simulation) -> float:
    """First-order bound on ``|E(t) - E(0)|`` from the tolerance: ``sum_k |dE/dy(y_k)| . sqrt(m)
    (atol + rtol max(|y_k-1|, |y_k|))``. The exact flow conserves E, so ``E(y_k) - E(y_k-1) = E(y_k)
    - E(flow(y_k-1)) ~ dE/dy . l_k`` with ``l_k`` the local error: the sum telescopes, and nothing
    amplifies it."""
    if sim.steps == 0:
        return 0.0
    m = sim.y.shape[1]
    grad = np.abs(energy_gradient(case, sim.y[1:]))
    sc = sim.atol + sim.rtol * np.maximum(np.abs(sim.y[:-1]), np.abs(sim.y[1:]))
    return float((grad * sc).sum() * math.sqrt(m))


@dataclass
class EnergyRun:
    case: str
    integrator: str
    rtol: float
    sim: fd.Simulation
    drift: float = math.nan          # max_k |E(t_k) - E(0)|, J
    scale: float = math.nan          # max kinetic energy reached, J
    bound: float = math.nan

    @property
    def passed(self) -> bool:
        return self.sim.ok and self.drift <= self.bound


def energy_drift(case: SpringCase, integrator: str, rtol: float, method: str = "pinocchio",
                 max_seconds: float | None = None, models: PreparedSet | None = None) -> EnergyRun:
    mech = case.mechanism
    d = mech.dof
    sim = fd.simulate(_models(models)(mech, method), case.q0, case.qd0, (0.0, case.horizon), case.controls,
                      integrator, rtol,
                      ATOL_FACTOR * rtol, max_seconds=max_seconds)
    run = EnergyRun(case.name, integrator, rtol, sim)
    if sim.steps:
        E = case.energy(sim.q(d), sim.qd(d))
        run.drift = float(np.abs(E - E[0]).max())
        run.scale = float(kinetic_energy(mech, sim.q(d), sim.qd(d)).max())
        run.bound = energy_bound(case, sim)
    return run


# ----------------------------------------------------------------------------- stiff variants
def hanging_chain(mass_scale: float = 1.0) -> tuple[Mechanism, np.ndarray]:
    """A planar three-link chain hanging from the support point, released from rest at
    angles -pi/2 + (0.5, 0.3, -0.4); ``mass_scale`` multiplies the masses of the last link."""
    base = chain(3, 2)
    masses = list(base.masses)
    masses[-1] = tuple(mass_scale * x for x in masses[-1])
    name = "chain3-2d hanging" + ("" if mass_scale == 1 else f", last link masses x{mass_scale:g}")
    mech = base.replace(masses=tuple(masses), name=name)
    q0 = np.array([-math.pi / 2 + 0.5, -math.pi / 2 + 0.3, -math.pi / 2 - 0.4, 0.43, 0.43, 0.43])
    return mech, q0


def stiff_case(k: float, mass_scale: float = 1.0, horizon: float = 1.0) -> SpringCase:
    """Critically damped stiff rods: ``c_i = 2 sqrt(k mu_ii)`` with ``mu_ii`` the mass that moves
    along rod i (the diagonal of M for ``l_i``), so each rod mode decays at ``sqrt(k / mu_ii)``
    without ringing: a stiff, not an oscillatory, problem."""
    mech, q0 = hanging_chain(mass_scale)
    mu = np.diag(fd.mass_distribution_matrix(mech))
    c = 2.0 * np.sqrt(k * mu)
    return SpringCase(f"{mech.name}, k = {k:.0e}", mech, q0, np.zeros_like(q0), k, c, q0[-3:], horizon,
                      f"{mech.name}: rods on critically damped springs k = {k:.0e} N/m, "
                      f"fastest rod mode {math.sqrt(k / mu.min()):.2e} rad/s")


@dataclass
class StiffRun:
    case: str
    integrator: str
    rtol: float
    sim: fd.Simulation
    stiffness: float                 # fastest rod rate sqrt(k / mu_ii), 1/s
    cond: float = math.nan           # cond(M) at the initial state
    error: float = math.nan          # |q(H) - q_ref(H)|, against a tight Radau run
    energy_change: float = math.nan  # max_k E(t_k) - E(0), J: the dampers only dissipate, so <= 0 up to rounding

    @property
    def solved(self) -> bool:
        return self.sim.ok


def stiff_run(case: SpringCase, integrator: str, rtol: float, max_evaluations: int, reference=None,
              method: str = "pinocchio", max_seconds: float | None = None,
              models: PreparedSet | None = None) -> StiffRun:
    mech = case.mechanism
    sim = fd.simulate(_models(models)(mech, method), case.q0, case.qd0, (0.0, case.horizon), case.controls,
                      integrator, rtol,
                      ATOL_FACTOR * rtol, max_evaluations=max_evaluations, max_seconds=max_seconds)
    mu = np.diag(fd.mass_distribution_matrix(mech))
    cond = float(fd.condition_numbers(_models(models)(mech, "pinocchio").mass_matrix(case.q0[None]))[0][0])
    run = StiffRun(case.name, integrator, rtol, sim, float(math.sqrt(case.k / mu.min())), cond)
    d = mech.dof
    if sim.ok and reference is not None and reference.ok:
        run.error = float(np.abs(sim.y[-1, :d] - reference.y[-1, :d]).max())
    if sim.ok:
        E = case.energy(sim.q(d), sim.qd(d))
        run.energy_change = float((E - E[0]).max())
    return run


# ----------------------------------------------------------------------------- plots
def work_precision_figure(panels: list[tuple[str, str, dict[str, list[tuple[float, float, float]]]]]):
    """One log-log panel per problem: x the error, y the run time, a line per integrator through
    its tolerances (each point labelled with its rtol exponent). ``panels``: (title, x label,
    {integrator: [(rtol, error, seconds), ...]})."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.2 * len(panels), 3.6), layout="constrained")
    axes = fig.subplots(1, len(panels), squeeze=False)[0]
    markers = {"RK45": "o", "DOP853": "s", "Radau": "^", "BDF": "v"}
    for ax, (title, xlabel, series) in zip(axes, panels):
        for integ, pts in series.items():
            pts = [p for p in pts if math.isfinite(p[1]) and p[1] > 0 and math.isfinite(p[2])]
            if not pts:
                continue
            r, e, s = map(np.array, zip(*sorted(pts)))
            ax.loglog(e, s, marker=markers.get(integ, "x"), label=integ, ms=4, lw=1)
            for ri, ei, si in zip(r, e, s):
                ax.annotate(f"{math.log10(ri):.0f}", (ei, si), fontsize=6, xytext=(2, 2), textcoords="offset points")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel("run time (s)", fontsize=8)
        ax.tick_params(which="both", labelsize=7)
        ax.grid(True, which="major", lw=0.3)
        ax.legend(fontsize=7)
    return fig


def stiff_figure(runs: list[StiffRun]):
    """Right-hand-side evaluations against the fastest rod rate, per integrator (log-log)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(5.0, 3.6), layout="constrained")
    ax = fig.subplots()
    by: dict[tuple[str, bool], list[StiffRun]] = {}
    for r in runs:
        by.setdefault((r.integrator, "masses x" in r.case), []).append(r)
    markers = {"RK45": "o", "DOP853": "s", "Radau": "^", "BDF": "v"}
    colors = {"RK45": "#1f77b4", "DOP853": "#ff7f0e", "Radau": "#2ca02c", "BDF": "#d62728"}
    for (integ, tiny), rs in by.items():
        rs = sorted(rs, key=lambda r: r.stiffness)
        x = [r.stiffness for r in rs]
        y = [r.sim.nfev for r in rs]
        if tiny:
            ax.scatter(x, y, marker=markers.get(integ, "x"), facecolors="none", edgecolors=colors.get(integ), s=40,
                       label=f"{integ}, tiny masses (k = 1e4)")
        else:
            ax.loglog(x, y, marker=markers.get(integ, "x"), color=colors.get(integ), label=f"{integ}, stiff k", ms=4,
                      lw=1)
        for r in rs:
            if not r.solved:
                ax.annotate("gave up", (r.stiffness, r.sim.nfev), fontsize=6, color="red")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("fastest rod rate sqrt(k / m) (1/s)", fontsize=8)
    ax.set_ylabel("right-hand-side evaluations", fontsize=8)
    ax.set_title("stiff rods: cost of one horizon", fontsize=9)
    ax.tick_params(which="both", labelsize=7)
    ax.grid(True, which="major", lw=0.3)
    ax.legend(fontsize=7)
    return fig



# ----------------------------------------------------------------------------- the report's experiments


def _e(x, digits: int = 1) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    return "inf" if math.isinf(x) else f"{x:.{digits}e}"


@dataclass
class TermsRow:
    mechanism: str
    method: str
    source: str                      # "exposed" or "from inverse dynamics"
    status: str = "ok"
    m_rel: float = math.nan          # max |M - M_crba| / max |M_crba|
    h_rel: float = math.nan
    seconds: float = math.nan


def terms_agreement(methods: list[str], samples: int = 4, models: PreparedSet | None = None) -> list[TermsRow]:
    """Each method's M and h (exposed or from its inverse dynamics) against Pinocchio's CRBA and
    ``nonLinearEffects``; Pinocchio itself also through its inverse dynamics (the linearity identity)."""
    import time

    from exo_bench.models.motion import random_states

    models = _models(models)
    rows = []
    for mech in (exo5(3), random_tree(5, 3, 9), exo5(2)):
        q, qd, _ = random_states(mech, samples, 21)
        pin_model = models(mech, "pinocchio")
        M0, h0 = pin_model.mass_matrix(q), pin_model.bias_forces(q, qd)
        plan = [(m, False) for m in methods] + [("pinocchio", True)]
        for m, via in plan:
            try:
                model = models(mech, m)
            except ImportError as e:   # a missing module is a row, not a crash
                rows.append(TermsRow(mech.name, m, "", "missing: " + one_line(e)))
                continue
            except Exception as e:  # noqa: BLE001 - over budget or failing to prepare: a row
                skip = getattr(e, "skip_reason", None)
                rows.append(TermsRow(mech.name, m, "", f"skipped: {skip}" if skip else "failed: " + one_line(e)))
                continue
            exposed = (not via) and model.native_terms
            row = TermsRow(mech.name, m, "exposed (CRBA, nonLinearEffects)" if m == "pinocchio" and exposed
                           else "exposed" if exposed else "from inverse dynamics")
            try:
                t0 = time.perf_counter()
                M, h = fd.mass_matrix_and_bias(model, q, qd, via_inverse_dynamics=via)
                row.seconds = time.perf_counter() - t0
                row.m_rel = float(np.abs(M - M0).max() / np.abs(M0).max())
                row.h_rel = float(np.abs(h - h0).max() / np.abs(h0).max())
            except Exception as e:  # noqa: BLE001
                skip = getattr(e, "skip_reason", None)
                row.status = f"skipped: {skip}" if skip else "failed: " + one_line(e)
            rows.append(row)
    return rows


@dataclass
class SingularDemo:
    case: str
    inverse: str                      # what inverse dynamics gives there
    forward: str                      # what forward dynamics says


def singular_demos(models: PreparedSet | None = None) -> list[SingularDemo]:
    """Forward dynamics at genuinely singular configurations: refused, with the link named."""
    from exo_bench.models.motion import gait, random_states

    models = _models(models)

    e3 = exo5(3)
    g = gait(e3, np.array([0.0]))
    q, qd, qdd = random_states(e3, 1, 5)
    q0 = q.copy()
    q0[0, -4] = 0.0   # l_2 = 0
    m = list(e3.masses)
    m[3] = (m[3][0], 0.0, 0.0)
    massless = e3.replace(masses=tuple(m), name="exo5-3d, massless swing shin")
    out = []
    for label, mech, (a, b, c) in (("exo5-3d gait of eq. (26) at t = 0 (trunk at psi5 = pi/2)", e3, (g.q, g.qd, g.qdd)),
                                   ("exo5-3d, random state with l2 = 0", e3, (q0, qd, qdd)),
                                   ("exo5-3d with a massless swing shin", massless, (q, qd, qdd))):
        model = models(mech, "pinocchio")
        tau = model.inverse_dynamics(a, b, c)
        inv = "finite" if np.isfinite(tau).all() else "NaN/Inf"
        try:
            fd.accelerations(model, a, b, tau)
            fwd = "accepted (NOT detected)"
        except fd.SingularConfigurationError as e:
            fwd = f"refused: {e.reasons[0]}"
        out.append(SingularDemo(label, inv, fwd))
    return out


@dataclass
class ForwardResults:
    profile: object
    terms: list[TermsRow]
    singular: list[SingularDemo]
    growth: dict[str, float]                        # round-trip case -> G(H)
    round_trips: list[RoundTrip]                    # every integrator x rtol, pinocchio
    method_trips: list[RoundTrip]                   # per method, DOP853
    refused: list[tuple[str, str]]                  # round trips refused (case, reason)
    energy: list[EnergyRun]
    stiff: list[StiffRun]
    stiff_wp: list[StiffRun]
    cases: dict[str, str]                           # name -> description
    seconds: float = 0.0
    stiff_notes: list[str] = field(default_factory=list)


def _grid(case: RoundTripCase, integrators, rtols, var, method="pinocchio", max_seconds=None,
          models: PreparedSet | None = None) -> list[RoundTrip]:
    """Every integrator at every tolerance; the run at rtol / TIGHTER (when in the grid) is the
    error estimate of the run at rtol."""
    out = []
    for integ in integrators:
        sims = {r: round_trip_run(case, integ, r, method, max_seconds=max_seconds, models=models) for r in rtols}
        for r in rtols:
            tighter = next((s for r2, s in sims.items() if math.isclose(r2, r / TIGHTER, rel_tol=1e-6)), None)
            out.append(round_trip(case, integ, r, method, var=var, sim=sims[r], tighter=tighter, estimate=False,
                                  models=models))
        for s in sims.values():
            s.solution = None          # the dense outputs served as estimates; they are large
    return out


def rt_failed(rt: RoundTrip) -> bool:
    return rt.verdict == "FAIL"


def run_forward(profile, methods: list[str], log=print, models: PreparedSet | None = None) -> ForwardResults:
    """Every forward-dynamics experiment of the report, at the profile's sizes."""
    import time

    from exo_bench.models.motion import gait

    t_start = time.perf_counter()
    log("forward dynamics: mass matrices and bias forces per method")
    models = _models(models)
    terms = terms_agreement(methods, models=models)
    sing = singular_demos(models)
    cases = [c for c in round_trip_cases(profile.full_cases) if not profile.rt_cases or c.name in profile.rt_cases]
    growth, trips, mtrips, refused = {}, [], [], []
    for i, case in enumerate(cases):
        log(f"forward dynamics: round trip {case.name}")
        ctrl = fd.prescribed_controls(models(case.mechanism, "pinocchio"), case.motion_of_t)
        m0 = case.motion_of_t(np.array([0.0]))
        var = variational(case.mechanism, ctrl, m0.q, m0.qd, case.horizon, models=models)
        growth[case.name] = var.max_growth()
        if i == 0:
            trips += _grid(case, fd.INTEGRATORS, profile.wp_rtols, var, models=models)
        else:
            trips += _grid(case, profile.rt_integrators, profile.rt_rtols, var, models=models)
        if case.name in profile.method_cases:
            for m in methods:
                log(f"forward dynamics: round trip {case.name} with {m}'s M and h")
                try:
                    sim = round_trip_run(case, "DOP853", profile.method_rtol, m, max_seconds=profile.method_seconds,
                                         models=models)
                    tight = (round_trip_run(case, "DOP853", profile.method_rtol / TIGHTER, m,
                                            max_seconds=profile.method_seconds, models=models) if sim.ok else None)
                    mtrips.append(round_trip(case, "DOP853", profile.method_rtol, m, var=var, sim=sim, tighter=tight,
                                             estimate=False, models=models))
                    sim.solution = None
                    if tight is not None:
                        tight.solution = None
                except Exception as e:  # noqa: BLE001 - a missing/over-budget method is a row
                    skip = getattr(e, "skip_reason", None)
                    rt = RoundTrip(case.name, m, "DOP853", profile.method_rtol,
                                   fd.Simulation("DOP853", profile.method_rtol, 0.0, np.zeros(0), np.zeros((0, 0)),
                                                 status=(f"skipped: {skip}" if skip else "failed: " + one_line(e))))
                    mtrips.append(rt)
                if rt_failed(mtrips[-1]):
                    warnings.warn(f"forward dynamics from {m!r}'s M and h does not reproduce the motion of "
                                  f"{case.name}: deviation {mtrips[-1].error:.1e} > tolerance "
                                  f"{mtrips[-1].tolerance:.1e}", UnusableMethodWarning, stacklevel=2)
    e3 = exo5(3)
    try:
        g = gait(e3, np.array([0.0]))
        e3_model = models(e3, "pinocchio")
        fd.simulate(e3_model, g.q, g.qd, (0.0, 0.1), fd.prescribed_controls(e3_model, lambda t: gait(e3, t)))
        refused.append(("exo5-3d gait of eq. (26)", "accepted (NOT detected)"))
    except fd.SingularConfigurationError as e:
        refused.append(("exo5-3d gait of eq. (26)", str(e)))
    log("forward dynamics: conservative case")
    springs = [c for c in conservative_cases() if not profile.energy_cases or c.name in profile.energy_cases]
    energy = [energy_drift(c, integ, r, max_seconds=profile.method_seconds, models=models) for c in springs
              for integ in fd.INTEGRATORS for r in profile.energy_rtols]
    log("forward dynamics: stiff rods")
    stiff, stiff_wp = [], []
    variants = [stiff_case(k) for k in profile.stiff_k] + [stiff_case(1e4, s) for s in profile.stiff_mass_scales]
    notes = []
    secs = profile.stiff_seconds
    for c in variants:
        r_ref = profile.stiff_reference_rtol
        ref = fd.simulate(models(c.mechanism, "pinocchio"), c.q0, c.qd0, (0.0, c.horizon), c.controls,
                          integrator="Radau", rtol=r_ref,
                          atol=ATOL_FACTOR * r_ref, max_seconds=secs)
        if not ref.ok:
            notes.append(f"{c.name}: the reference (Radau, rtol {r_ref:.0e}) did not finish: {ref.status}")
        for integ in fd.INTEGRATORS:
            stiff.append(stiff_run(c, integ, profile.stiff_rtol, profile.stiff_budget, ref, max_seconds=secs,
                                   models=models))
        if c.k == 1e6 and c.mechanism.name == "chain3-2d hanging":
            for integ in fd.INTEGRATORS:
                for r in (1e-3, 1e-4, 1e-5):
                    stiff_wp.append(stiff_run(c, integ, r, profile.stiff_budget, ref, max_seconds=secs,
                                                    models=models))
            stiff_wp += [s for s in stiff if s.case == c.name]
    descr = {c.name: c.description for c in cases}
    descr.update({c.name: c.description for c in springs})
    descr.update({c.name: c.description for c in variants})
    return ForwardResults(profile, terms, sing, growth, trips, mtrips, refused, energy, stiff, stiff_wp, descr,
                          time.perf_counter() - t_start, notes)


def forward_markdown(res: ForwardResults) -> str:
    p = res.profile
    L = ["## Forward dynamics", "",
         "`M(q) qdd + h(q, qd) = tau` solved for qdd (`models.forward_dynamics`): Pinocchio's M and h from CRBA and "
         "`nonLinearEffects` (its ABA refuses the URDF's mimic joints), other methods' from the functions they "
         "expose or, exactly, from their inverse dynamics (it is linear in qdd: h = ID(q, qd, 0), M e_k = "
         "ID(q, 0, e_k) - ID(q, 0, 0), one batched call per evaluation). The solve is equilibrated by diag(M). "
         "Integration: scipy `solve_ivp`, RK45 and DOP853 (explicit), Radau and BDF (implicit, Jacobian "
         f"estimated by scipy from the vectorised right-hand side); atol = {ATOL_FACTOR:g} * rtol.", "",
         "### Each method's M and h against CRBA", "",
         "| mechanism | method | M and h | max rel. diff M | max rel. diff h | seconds (4 states) |",
         "|---|---|---|---|---|---|"]
    for r in res.terms:
        if r.status != "ok":
            L.append(f"| {r.mechanism} | {r.method} | {r.source} | {r.status} | | |")
        else:
            L.append(f"| {r.mechanism} | {r.method} | {r.source} | {_e(r.m_rel)} | {_e(r.h_rel)} | {r.seconds:.3f} |")
    L += ["", "### Singular configurations", "",
          "| configuration | inverse dynamics | forward dynamics |", "|---|---|---|"]
    L += [f"| {s.case} | {s.inverse} | {s.forward} |" for s in res.singular]
    for name, why in res.refused:
        L += ["", f"**Round trip on the {name} is refused: {why}.** The trunk of eq. (26) stands exactly "
              "vertical (psi5 = pi/2) at every instant: its azimuth is undefined, M is singular, so the spatial gait "
              "has inverse dynamics but no forward dynamics in the paper's coordinates. The round trip below uses "
              "the planar gait and random motions instead."]
    L += ["", "### Round trip: controls from inverse dynamics reproduce the prescribed motion", "",
          "Controls tau(t) = ID_pinocchio(q*(t), qd*(t), qdd*(t)), evaluated on the fly at every time the integrator "
          "asks for (no interpolation), drive the forward dynamics from (q*(0), qd*(0)); the deviation is "
          "measured at every accepted step, max over time and coordinates (rad or m).", "",
          f"**Tolerance.** {ROUND_TRIP_RULE}", "",
          "The a priori column is the first-order worst case sum_k |Phi(t_j, t_k)|_q sqrt(m) (atol + rtol |y_k|) "
          "over the accepted steps (each local error passes scipy's RMS test, so each component is below sqrt(m) "
          "times its scale, and is carried to t_j by the linearised flow Phi, computed from 2 dof perturbed copies). "
          "It always holds and is far from sharp: the error estimators of these methods are pessimistic "
          "(local extrapolation), so the pass rule uses the a posteriori estimate.", ""]
    L += ["| case | growth G(H) | description |", "|---|---|---|"]
    L += [f"| {c} | {_e(g)} | {res.cases[c]} |" for c, g in res.growth.items()]
    L += ["", "| case | integrator | rtol | steps | RHS evals | seconds | deviation from q* | estimate E | floor F | "
          "tolerance 2E + F | a priori bound | verdict |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for rt in res.round_trips:
        v = rt.verdict if rt.verdict != "FAIL" else "**FAIL**"
        L.append(f"| {rt.case} | {rt.integrator} | {rt.rtol:.0e} | {rt.sim.steps} | {rt.sim.nfev} | "
                 f"{rt.sim.seconds:.2f} | {_e(rt.error)} | {_e(rt.estimate)} | {_e(rt.floor)} | "
                 f"{_e(rt.tolerance) if math.isfinite(rt.estimate) else ''} | {_e(rt.bound)} | {v} |")
    judged = [rt for rt in res.round_trips if math.isfinite(rt.estimate)]
    npass = sum(rt.passed for rt in judged)
    L += ["", f"**{npass} of {len(judged)} judged round trips pass** (the others have no tighter run in the grid)."]
    if res.method_trips:
        L += ["", f"Per method: forward dynamics from each method's M and h (DOP853, rtol {p.method_rtol:.0e}, "
              f"estimate from rtol {p.method_rtol / TIGHTER:.0e}), the same controls (Pinocchio's inverse dynamics), "
              "so a method passes only if its M and h agree with Pinocchio's RNEA:", "",
              "| case | method | steps | seconds | deviation from q* | estimate E | tolerance | verdict |",
              "|---|---|---|---|---|---|---|---|"]
        for rt in res.method_trips:
            if not rt.sim.ok:
                L.append(f"| {rt.case} | {rt.method} | | | | | | {rt.sim.status} |")
                continue
            v = rt.verdict if rt.verdict != "FAIL" else "**FAIL**"
            L.append(f"| {rt.case} | {rt.method} | {rt.sim.steps} | {rt.sim.seconds:.2f} | {_e(rt.error)} | "
                     f"{_e(rt.estimate)} | {_e(rt.tolerance)} | {v} |")
    L += ["", "### Conservative case: energy drift", "",
          "No actuators; the rods carry springs F = -k (l - l*) with no damping (without them the free telescopes "
          "collapse to l = 0, where M is singular, or extend without bound), so E = T + Pi + sum k/2 (l - l*)^2 "
          "(`models.kinematics.total_energy` plus the springs) is conserved by the exact flow.", "",
          "**Tolerance.** E(y_k) - E(y_k-1) = E(y_k) - E(flow(y_k-1)) ~ dE/dy . l_k with l_k the local error of step "
          "k: the drift is a sum of local errors weighted by the energy gradient and is never amplified (E is a "
          "first integral). With |l_k,i| <= sqrt(m) (atol + rtol |y_k,i|) (scipy's RMS test), the bound is "
          "sum_k |dE/dy(y_k)| . sqrt(m) (atol + rtol |y_k|), computed along the run (gradient by central "
          "differences).", "",
          "| case | integrator | rtol | steps | seconds | max drift (J) | drift / max T | bound (J) | verdict |",
          "|---|---|---|---|---|---|---|---|---|"]
    for r in res.energy:
        v = ("pass" if r.passed else "**FAIL**") if r.sim.ok else r.sim.status
        L.append(f"| {r.case} | {r.integrator} | {r.rtol:.0e} | {r.sim.steps} | {r.sim.seconds:.2f} | {_e(r.drift)} | "
                 f"{_e(r.drift / r.scale if r.scale else math.nan)} | {_e(r.bound)} | {v} |")
    L += ["", f"### Stiff rods and tiny masses (rtol {p.stiff_rtol:.0e}, at most {p.stiff_budget} right-hand-side "
          f"evaluations or {p.stiff_seconds:g} s per run)", "",
          "Rods on critically damped springs (c_i = 2 sqrt(k mu_ii), so the rod modes decay at sqrt(k / mu_ii) without "
          "ringing) in a hanging three-link chain released from rest; tiny masses on the last link at k = 1e4 give "
          f"the same stiffness through the mass. The error is |q(H) - q_ref(H)| against Radau at rtol "
          f"{p.stiff_reference_rtol:.0e}. The "
          "dampers only dissipate, so E = T + Pi + springs never rises along the exact flow: a positive "
          "`max E - E(0)` can only be integration error.", "",
          "| case | fastest rod rate (1/s) | cond(M) at start | integrator | status | RHS evals | steps | Jacobians | "
          "LU | seconds | error at H | max E - E(0) (J) |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in res.stiff:
        st = "solved" if r.solved else f"**{r.sim.status}**"
        L.append(f"| {r.case} | {r.stiffness:.1e} | {_e(r.cond)} | {r.integrator} | {st} | {r.sim.nfev} | "
                 f"{r.sim.steps} | {r.sim.njev} | {r.sim.nlu} | {r.sim.seconds:.2f} | {_e(r.error)} | "
                 f"{_e(r.energy_change)} |")
    if res.stiff_notes:
        L += [""] + [f"- {n}" for n in res.stiff_notes]
        L += ["", "A reference that does not finish at a tight tolerance is itself a finding: where cond(M) is large "
              "(tiny masses), the right-hand side is accurate to about cond(M) * eps only, below which the error "
              "estimates of the implicit integrators are noise and their steps collapse."]
    expl = [r for r in res.stiff if r.integrator in fd.EXPLICIT]
    impl = [r for r in res.stiff if r.integrator in fd.IMPLICIT]
    if expl and impl:
        stiffest = max(r.stiffness for r in res.stiff)
        e_max = max(r.sim.nfev for r in expl if r.stiffness == stiffest)
        i_max = max(r.sim.nfev for r in impl if r.stiffness == stiffest)
        L += ["", f"At the stiffest variant ({stiffest:.1e} 1/s) the explicit integrators used up to {e_max} "
              f"evaluations{' (or gave up)' if any(not r.solved for r in expl) else ''}, the implicit ones at most "
              f"{i_max}: explicit step sizes are bounded by stability (h ~ 3 / rate), implicit ones by accuracy."]
    return "\n".join(L) + "\n"


def forward_figures(res: ForwardResults) -> dict[str, object]:
    """``stability-work-precision.png`` and ``stability-stiff.png``."""
    first = next(iter(res.growth), None)
    rt_series: dict[str, list] = {}
    for rt in res.round_trips:
        if rt.case == first:
            rt_series.setdefault(rt.integrator, []).append((rt.rtol, rt.error, rt.sim.seconds))
    en_series: dict[str, list] = {}
    e_first = res.energy[0].case if res.energy else None
    for r in res.energy:
        if r.case == e_first:
            en_series.setdefault(r.integrator, []).append((r.rtol, r.drift / r.scale, r.sim.seconds))
    st_series: dict[str, list] = {}
    for r in res.stiff_wp:
        if r.solved:
            st_series.setdefault(r.integrator, []).append((r.rtol, r.error, r.sim.seconds))
    panels = [(f"round trip: {first}", "max |q - q*| (rad, m)", rt_series),
              (f"energy drift: {e_first}", "max |E - E0| / max T", en_series)]
    if st_series:
        panels.append((f"stiff: {res.stiff_wp[0].case}", "|q(H) - q_ref(H)|", st_series))
    return {"stability-work-precision.png": work_precision_figure(panels),
            "stability-stiff.png": stiff_figure(res.stiff)}
