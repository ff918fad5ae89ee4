"""Forward-dynamics study, the evaluation: :func:`run_forward` runs every part (the round trips of
``forward_round_trip``, the energy drift and stiff rods of ``forward_energy``, the terms per method and
singular configurations of ``forward_terms``) over a profile's grid into :class:`ForwardResults`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
import warnings

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
from exo_bench.models.mechanism.presets import exo5
from exo_bench.bench.studies.stability.forward_energy import EnergyRun, StiffRun, energy_drift, stiff_run
from exo_bench.bench.studies.stability.forward_round_trip import RoundTrip, round_trip, round_trip_run, variational
from exo_bench.bench.studies.stability.forward_terms import SingularDemo, TermsRow, singular_demos, terms_agreement


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
    # the implicit integrators with the analytic Jacobian (models.forward_dynamics.make_jacobian): the
    # work-precision round trip and the stiff work-precision case again (bench/studies/stability/forward_jacobian.py)
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
                        fd.Simulation(
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
        fd.simulate(e3_model, g.q, g.qd, (0.0, 0.1), fd.prescribed_controls(e3_model, lambda t: gait(e3, t)))
        refused.append(("exo5-3d gait of eq. (26)", "accepted (NOT detected)"))
    except fd.SingularConfigurationError as e:
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
        ref = fd.simulate(
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
