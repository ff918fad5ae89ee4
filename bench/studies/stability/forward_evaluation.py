"""Forward-dynamics study, the evaluation: :func:`run_forward` runs every part (the round trips of
:mod:`exo_bench.bench.studies.stability.forward_round_trip`; the energy drift and stiff rods, the terms
per method and singular configurations, defined here) over a profile's grid into :class:`ForwardResults`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from exo_bench.api import PreparedSet
from exo_bench.bench.studies.stability.cases import Profile
from exo_bench.bench.studies.stability.forward_cases import (
    ATOL_FACTOR,
    RoundTripCase,
    SpringCase,
    TIGHTER,
    _models,
    conservative_cases,
    round_trip_cases,
    stiff_case,
)
from exo_bench.bench.studies.study import UnusableMethodWarning
from exo_bench.bench.studies.study import one_line
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.simulation.forward_dynamics import Simulation, simulate
from exo_bench.models.mechanism.singularity import SingularConfigurationError
from exo_bench.models.mechanism.presets import exo5
from exo_bench.bench.studies.stability.forward_round_trip import RoundTrip, round_trip, round_trip_run, variational
from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.mechanism.kinematics import kinetic_energy
from exo_bench.api import METHODS
from exo_bench.models.mechanism.presets import random_tree


# Forward-dynamics study, conservative and stiff systems: the energy drift of each integrator against its bound,
# and the stiff rods (work against precision within an evaluation budget).


def energy_gradient(case: SpringCase, y: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """``dE/dy (N, m)`` by central differences (one batched energy call)."""
    N, m = y.shape
    d = m // 2
    steps = h * np.maximum(1.0, np.abs(y))  # (N, m)
    Y = np.repeat(y[:, None, :], 2 * m, axis=1)  # (N, 2m, m)
    idx = np.arange(m)
    Y[:, idx, idx] += steps
    Y[:, m + idx, idx] -= steps
    E = case.energy(Y[..., :d].reshape(-1, d), Y[..., d:].reshape(-1, d)).reshape(N, 2 * m)
    return (E[:, :m] - E[:, m:]) / (2 * steps)


def energy_bound(case: SpringCase, sim: Simulation) -> float:
    """First-order bound on ``|E(t) - E(0)|`` from the tolerance.

    It is ``sum_k |dE/dy(y_k)| . sqrt(m) (atol + rtol max(|y_k-1|, |y_k|))``. The exact flow conserves E, so ``E(y_k) - E(y_k-1) = E(y_k)
    - E(flow(y_k-1)) ~ dE/dy . l_k`` with ``l_k`` the local error: the sum telescopes, and nothing
    amplifies it."""
    if sim.steps == 0:
        return 0.0
    m = sim.y.shape[1]
    grad = np.abs(energy_gradient(case, sim.y[1:]))
    sc = sim.atol + sim.rtol * np.maximum(np.abs(sim.y[:-1]), np.abs(sim.y[1:]))
    return float((grad * sc).sum() * math.sqrt(m))


def _simulate_spring(
    case: SpringCase, integrator: str, rtol: float, method: str, models: PreparedSet | None, **budget
) -> Simulation:  # budget: max_evaluations, max_seconds (and jacobian)
    """A spring case integrated from its initial state over its horizon with ``method``'s ``M`` and
    ``h`` (atol = ``ATOL_FACTOR`` rtol); ``budget``: ``max_evaluations``, ``max_seconds``."""
    return simulate(
        _models(models)(case.mechanism, method),
        case.q0,
        case.qd0,
        (0.0, case.horizon),
        case.controls,
        integrator,
        rtol,
        ATOL_FACTOR * rtol,
        **budget,
    )


@dataclass
class EnergyRun:
    case: str
    integrator: str
    rtol: float
    sim: Simulation
    drift: float = math.nan  # max_k |E(t_k) - E(0)|, J
    scale: float = math.nan  # max kinetic energy reached, J
    bound: float = math.nan

    @property
    def passed(self) -> bool:
        return self.sim.ok and self.drift <= self.bound


def energy_drift(
    case: SpringCase,
    integrator: str,
    rtol: float,
    method: str = "pinocchio",
    max_seconds: float | None = None,
    models: PreparedSet | None = None,
) -> EnergyRun:
    mech = case.mechanism
    d = mech.dof
    sim = _simulate_spring(case, integrator, rtol, method, models, max_seconds=max_seconds)
    run = EnergyRun(case.name, integrator, rtol, sim)
    if sim.steps:
        E = case.energy(sim.q(d), sim.qd(d))
        run.drift = float(np.abs(E - E[0]).max())
        run.scale = float(kinetic_energy(mech, sim.q(d), sim.qd(d)).max())
        run.bound = energy_bound(case, sim)
    return run


@dataclass
class StiffRun:
    case: str
    integrator: str
    rtol: float
    sim: Simulation
    stiffness: float  # fastest rod rate sqrt(k / mu_ii), 1/s
    cond: float = math.nan  # cond(M) at the initial state
    error: float = math.nan  # |q(H) - q_ref(H)|, against a tight Radau run
    energy_change: float = math.nan  # max_k E(t_k) - E(0), J: the dampers only dissipate, so <= 0 up to rounding

    @property
    def solved(self) -> bool:
        return self.sim.ok


def stiff_run(
    case: SpringCase,
    integrator: str,
    rtol: float,
    max_evaluations: int,
    reference=None,
    method: str = "pinocchio",
    max_seconds: float | None = None,
    models: PreparedSet | None = None,
    jacobian: str = "finite-difference",
) -> StiffRun:
    mech = case.mechanism
    sim = _simulate_spring(
        case,
        integrator,
        rtol,
        method,
        models,
        max_evaluations=max_evaluations,
        max_seconds=max_seconds,
        jacobian=jacobian,
    )
    mu = np.diag(coupling(mech))
    cond = float(fd.condition_numbers(_models(models)(mech, "pinocchio").mass_matrix(case.q0[None]))[0][0])
    run = StiffRun(case.name, integrator, rtol, sim, float(math.sqrt(case.k / mu.min())), cond)
    d = mech.dof
    if sim.ok and reference is not None and reference.ok:
        run.error = float(np.abs(sim.y[-1, :d] - reference.y[-1, :d]).max())
    if sim.ok:
        E = case.energy(sim.q(d), sim.qd(d))
        run.energy_change = float((E - E[0]).max())
    return run


# Forward-dynamics study, the terms per method: mass matrices and bias forces against Pinocchio's, and the
# singular configurations each method names.


@dataclass
class TermsRow:
    mechanism: str
    method: str
    source: str  # "exposed" or "from inverse dynamics"
    status: str = "ok"
    m_rel: float = math.nan  # max |M - M_crba| / max |M_crba|
    h_rel: float = math.nan
    seconds: float = math.nan


def terms_agreement(methods: list[str], samples: int = 4, models: PreparedSet | None = None) -> list[TermsRow]:
    """Each method's M and h (exposed or from its inverse dynamics) against Pinocchio's CRBA and
    ``nonLinearEffects``; Pinocchio itself also through its inverse dynamics (the linearity identity)."""
    import time

    from exo_bench.models.gait.motion import random_states

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
            except ImportError as e:  # a missing module is a row, not a crash
                rows.append(TermsRow(mech.name, m, "", "missing: " + one_line(e)))
                continue
            except Exception as e:  # noqa: BLE001 - over budget or failing to prepare: a row
                skip = getattr(e, "skip_reason", None)
                rows.append(TermsRow(mech.name, m, "", f"skipped: {skip}" if skip else "failed: " + one_line(e)))
                continue
            exposed = (not via) and model.native_terms
            source = METHODS[m].exposed_terms if m in METHODS else None
            row = TermsRow(
                mech.name,
                m,
                (f"exposed ({source})" if source else "exposed") if exposed else "from inverse dynamics",
            )
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
    inverse: str  # what inverse dynamics gives there
    forward: str  # what forward dynamics says


def singular_demos(models: PreparedSet | None = None) -> list[SingularDemo]:
    """Forward dynamics at genuinely singular configurations: refused, with the link named."""
    from exo_bench.models.gait.motion import gait, random_states

    models = _models(models)

    e3 = exo5(3)
    g = gait(e3, np.array([0.0]))
    q, qd, qdd = random_states(e3, 1, 5)
    q0 = q.copy()
    q0[0, -4] = 0.0  # l_2 = 0
    m = list(e3.masses)
    m[3] = (m[3][0], 0.0, 0.0)
    massless = e3.replace(masses=tuple(m), name="exo5-3d, massless swing shin")
    out = []
    for label, mech, (a, b, c) in (
        ("exo5-3d gait of eq. (26) at t = 0 (trunk at psi5 = pi/2)", e3, (g.q, g.qd, g.qdd)),
        ("exo5-3d, random state with l2 = 0", e3, (q0, qd, qdd)),
        ("exo5-3d with a massless swing shin", massless, (q, qd, qdd)),
    ):
        model = models(mech, "pinocchio")
        tau = model.inverse_dynamics(a, b, c)
        inv = "finite" if np.isfinite(tau).all() else "NaN/Inf"
        try:
            fd.accelerations(model, a, b, tau)
            fwd = "accepted (NOT detected)"
        except SingularConfigurationError as e:
            fwd = f"refused: {e.reasons[0]}"
        out.append(SingularDemo(label, inv, fwd))
    return out


@dataclass
class ForwardResults:
    profile: Profile
    terms: list[TermsRow]
    singular: list[SingularDemo]
    growth: dict[str, float]  # round-trip case -> G(H)
    round_trips: list[RoundTrip]  # every integrator x rtol, pinocchio
    method_trips: list[RoundTrip]  # per method, DOP853
    refused: list[tuple[str, str]]  # round trips refused (case, reason)
    energy: list[EnergyRun]
    stiff: list[StiffRun]
    stiff_wp: list[StiffRun]
    cases: dict[str, str]  # name -> description
    seconds: float = 0.0
    stiff_notes: list[str] = field(default_factory=list)
    # the implicit integrators with the analytic Jacobian (models.simulation.simulate.make_jacobian): the
    # work-precision round trip and the stiff work-precision case again (bench/studies/stability/forward_report.py)
    analytic_trips: list[RoundTrip] = field(default_factory=list)
    analytic_stiff: list[StiffRun] = field(default_factory=list)
    analytic_notes: list[str] = field(default_factory=list)


def _grid(
    case: RoundTripCase,
    integrators,
    rtols,
    var,
    method="pinocchio",
    max_seconds=None,
    models: PreparedSet | None = None,
    jacobian: str = "finite-difference",
) -> list[RoundTrip]:
    """Every integrator at every tolerance; the run at rtol / TIGHTER (when in the grid) is the
    error estimate of the run at rtol."""
    out = []
    for integ in integrators:
        sims = {
            r: round_trip_run(case, integ, r, method, max_seconds=max_seconds, models=models, jacobian=jacobian)
            for r in rtols
        }
        for r in rtols:
            tighter = next((s for r2, s in sims.items() if math.isclose(r2, r / TIGHTER, rel_tol=1e-6)), None)
            out.append(
                round_trip(case, integ, r, method, var=var, sim=sims[r], tighter=tighter, estimate=False, models=models)
            )
        for s in sims.values():
            s.solution = None  # the dense outputs served as estimates; they are large
    return out


def analytic_grid(case: RoundTripCase, rtols, var, models: PreparedSet | None) -> tuple[list[RoundTrip], list[str]]:
    """The round trip of :func:`_grid` for the implicit integrators with the analytic Jacobian
    (``jacobian="analytic"``); without the derivatives (the extra ``casadi``) no rows and a note."""
    try:
        return _grid(case, fd.IMPLICIT, rtols, var, models=models, jacobian="analytic"), []
    except ValueError as e:
        return [], [f"{case.name}: no analytic Jacobian: {one_line(e)}"]


def analytic_stiff(
    case: SpringCase, rtols, budget: int, reference, max_seconds, models: PreparedSet | None, notes: list[str]
) -> list[StiffRun]:
    """:func:`stiff_run` of the implicit integrators with the analytic Jacobian at ``rtols``; a
    missing extra ``casadi`` is a note in ``notes``, not a crash."""
    try:
        return [
            stiff_run(case, integ, r, budget, reference, max_seconds=max_seconds, models=models, jacobian="analytic")
            for integ in fd.IMPLICIT
            for r in rtols
        ]
    except ValueError as e:
        notes.append(f"{case.name}: no analytic Jacobian: {one_line(e)}")
        return []


def rt_failed(rt: RoundTrip) -> bool:
    return rt.verdict == "FAIL"


def run_forward(profile, methods: list[str], log=print, models: PreparedSet | None = None) -> ForwardResults:
    """Every forward-dynamics experiment of the report, at the profile's sizes."""
    import time

    from exo_bench.models.gait.motion import gait

    t_start = time.perf_counter()
    log("forward dynamics: mass matrices and bias forces per method")
    models = _models(models)
    terms = terms_agreement(methods, models=models)
    sing = singular_demos(models)
    cases = [c for c in round_trip_cases(profile.full_cases) if not profile.rt_cases or c.name in profile.rt_cases]
    growth, trips, mtrips, refused = {}, [], [], []
    a_trips: list[RoundTrip] = []
    a_stiff: list[StiffRun] = []
    a_notes: list[str] = []
    for i, case in enumerate(cases):
        log(f"forward dynamics: round trip {case.name}")
        ctrl = fd.prescribed_controls(models(case.mechanism, "pinocchio"), case.motion_of_t)
        m0 = case.motion_of_t(np.array([0.0]))
        var = variational(case.mechanism, ctrl, m0.q, m0.qd, case.horizon, models=models)
        growth[case.name] = var.max_growth()
        if i == 0:
            trips += _grid(case, fd.INTEGRATORS, profile.wp_rtols, var, models=models)
            log(f"forward dynamics: round trip {case.name}, implicit integrators with the analytic Jacobian")
            a_trips, a_notes = analytic_grid(case, profile.wp_rtols, var, models)
        else:
            trips += _grid(case, profile.rt_integrators, profile.rt_rtols, var, models=models)
        if case.name in profile.method_cases:
            for m in methods:
                log(f"forward dynamics: round trip {case.name} with {m}'s M and h")
                try:
                    sim = round_trip_run(
                        case, "DOP853", profile.method_rtol, m, max_seconds=profile.method_seconds, models=models
                    )
                    tight = (
                        round_trip_run(
                            case,
                            "DOP853",
                            profile.method_rtol / TIGHTER,
                            m,
                            max_seconds=profile.method_seconds,
                            models=models,
                        )
                        if sim.ok
                        else None
                    )
                    mtrips.append(
                        round_trip(
                            case,
                            "DOP853",
                            profile.method_rtol,
                            m,
                            var=var,
                            sim=sim,
                            tighter=tight,
                            estimate=False,
                            models=models,
                        )
                    )
                    sim.solution = None
                    if tight is not None:
                        tight.solution = None
                except Exception as e:  # noqa: BLE001 - a missing/over-budget method is a row
                    skip = getattr(e, "skip_reason", None)
                    rt = RoundTrip(
                        case.name,
                        m,
                        "DOP853",
                        profile.method_rtol,
                        Simulation(
                            "DOP853",
                            profile.method_rtol,
                            0.0,
                            np.zeros(0),
                            np.zeros((0, 0)),
                            status=(f"skipped: {skip}" if skip else "failed: " + one_line(e)),
                        ),
                    )
                    mtrips.append(rt)
                if rt_failed(mtrips[-1]):
                    warnings.warn(
                        f"forward dynamics from {m!r}'s M and h does not reproduce the motion of "
                        f"{case.name}: deviation {mtrips[-1].error:.1e} > tolerance "
                        f"{mtrips[-1].tolerance:.1e}",
                        UnusableMethodWarning,
                        stacklevel=2,
                    )
    e3 = exo5(3)
    try:
        g = gait(e3, np.array([0.0]))
        e3_model = models(e3, "pinocchio")
        simulate(e3_model, g.q, g.qd, (0.0, 0.1), fd.prescribed_controls(e3_model, lambda t: gait(e3, t)))
        refused.append(("exo5-3d gait of eq. (26)", "accepted (NOT detected)"))
    except SingularConfigurationError as e:
        refused.append(("exo5-3d gait of eq. (26)", str(e)))
    log("forward dynamics: conservative case")
    springs = [c for c in conservative_cases() if not profile.energy_cases or c.name in profile.energy_cases]
    energy = [
        energy_drift(c, integ, r, max_seconds=profile.method_seconds, models=models)
        for c in springs
        for integ in fd.INTEGRATORS
        for r in profile.energy_rtols
    ]
    log("forward dynamics: stiff rods")
    stiff, stiff_wp = [], []
    variants = [stiff_case(k) for k in profile.stiff_k] + [stiff_case(1e4, s) for s in profile.stiff_mass_scales]
    notes = []
    secs = profile.stiff_seconds
    for c in variants:
        r_ref = profile.stiff_reference_rtol
        ref = simulate(
            models(c.mechanism, "pinocchio"),
            c.q0,
            c.qd0,
            (0.0, c.horizon),
            c.controls,
            integrator="Radau",
            rtol=r_ref,
            atol=ATOL_FACTOR * r_ref,
            max_seconds=secs,
        )
        if not ref.ok:
            notes.append(f"{c.name}: the reference (Radau, rtol {r_ref:.0e}) did not finish: {ref.status}")
        for integ in fd.INTEGRATORS:
            stiff.append(
                stiff_run(c, integ, profile.stiff_rtol, profile.stiff_budget, ref, max_seconds=secs, models=models)
            )
        if c.k == 1e6 and c.mechanism.name == "chain3-2d hanging":
            for integ in fd.INTEGRATORS:
                for r in (1e-3, 1e-4, 1e-5):
                    stiff_wp.append(stiff_run(c, integ, r, profile.stiff_budget, ref, max_seconds=secs, models=models))
            stiff_wp += [s for s in stiff if s.case == c.name]
            a_stiff = analytic_stiff(
                c, (1e-3, 1e-4, 1e-5, profile.stiff_rtol), profile.stiff_budget, ref, secs, models, a_notes
            )
    descr = {c.name: c.description for c in cases}
    descr.update({c.name: c.description for c in springs})
    descr.update({c.name: c.description for c in variants})
    return ForwardResults(
        profile,
        terms,
        sing,
        growth,
        trips,
        mtrips,
        refused,
        energy,
        stiff,
        stiff_wp,
        descr,
        time.perf_counter() - t_start,
        notes,
        a_trips,
        a_stiff,
        a_notes,
    )
