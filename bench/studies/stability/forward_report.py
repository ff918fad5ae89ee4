"""Forward-dynamics study, the report: its sections of ``reports/stability.md``, the implicit
integrators with the analytic Jacobian against scipy's finite differences among them."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from exo_bench.bench.output.provenance import sci
from exo_bench.bench.studies.stability.forward_cases import ATOL_FACTOR, ROUND_TRIP_RULE, TIGHTER
from exo_bench.bench.studies.stability.forward_evaluation import ForwardResults
from exo_bench.models.simulation import forward_dynamics as fd


# Forward-dynamics study: the implicit integrators with the analytic Jacobian against scipy's finite
# differences, the report section.

if TYPE_CHECKING:
    from exo_bench.models.simulation.forward_dynamics import Simulation


@dataclass
class Pair:
    """One case, integrator and rtol, run with both Jacobians."""

    case: str
    integrator: str
    rtol: float
    error_name: str  # what ``error`` measures
    fd: Simulation  # with scipy's finite differences
    analytic: Simulation  # with the analytic Jacobian
    fd_error: float
    analytic_error: float

    @property
    def both_ok(self) -> bool:
        return self.fd.ok and self.analytic.ok

    @property
    def fewer(self) -> bool:
        return self.both_ok and self.analytic.nfev < self.fd.nfev

    @property
    def same_tolerance(self) -> bool:
        """Both runs met the same rtol/atol: scipy accepted every step of both, and their errors agree
        within a factor of :data:`SAME_ERROR` (an error estimate is only good to its order of magnitude)."""
        if not self.both_ok:
            return False
        a, f = self.analytic_error, self.fd_error
        if not (math.isfinite(a) and math.isfinite(f)):
            return False
        return a <= SAME_ERROR * max(f, 1e-300) and f <= SAME_ERROR * max(a, 1e-300)


#: Errors within this factor of each other count as "the same tolerance reached" (both runs pass
#: scipy's error test at the same rtol/atol; their global errors differ by the luck of the steps).
SAME_ERROR = 3.0
#: The start of the table's header: in a report only when the analytic runs ran (before issue 36 they
#: needed the extra ``casadi``; a report without them is never written over one with them).
TABLE_HEAD = "| case | integrator | rtol | RHS evals FD |"


def pairs(res: ForwardResults) -> list[Pair]:
    """Every analytic run of ``res`` with its finite-difference twin (same case, integrator, rtol)."""
    out = []
    fd_trips = {(r.case, r.integrator, r.rtol): r for r in res.round_trips}
    for a in res.analytic_trips:
        f = fd_trips.get((a.case, a.integrator, a.rtol))
        if f is not None:
            out.append(Pair(a.case, a.integrator, a.rtol, "max |q - q*| (rad, m)", f.sim, a.sim, f.error, a.error))
    fd_stiff = {(r.case, r.integrator, r.rtol): r for r in (*res.stiff_wp, *res.stiff)}
    for s in res.analytic_stiff:
        g = fd_stiff.get((s.case, s.integrator, s.rtol))
        if g is not None:
            out.append(Pair(s.case, s.integrator, s.rtol, "|q(H) - q_ref(H)| (rad, m)", g.sim, s.sim, g.error, s.error))
    return out


def verdict(ps: list[Pair]) -> str:
    """One sentence, computed: does the analytic Jacobian reach the same tolerance in fewer
    right-hand-side evaluations?"""
    ok = [p for p in ps if p.both_ok]
    if not ok:
        return "No pair of runs finished with both Jacobians: no verdict."
    fewer = [p for p in ok if p.fewer]
    same = [p for p in ok if p.same_tolerance]
    both = [p for p in ok if p.fewer and p.same_tolerance]
    saved = [1 - p.analytic.nfev / p.fd.nfev for p in ok]
    yes = len(both) == len(ok)
    text = (
        f"**{'Yes' if yes else 'Not everywhere'}: the analytic Jacobian reached the same tolerance in fewer "
        f"right-hand-side evaluations in {len(both)} of {len(ok)} pairs** ({len(fewer)} used fewer evaluations, "
        f"{len(same)} reached an error within {SAME_ERROR:g}x of the finite-difference run's); it saved "
        f"{100 * min(saved):.0f}% to {100 * max(saved):.0f}% of the evaluations: the 2 dof columns of each of "
        "scipy's finite-difference Jacobians, and Newton iterations, since the analytic Jacobian is the current "
        "state's at every step."
    )
    return text + "".join(" " + reason(p) for p in ok if not (p.fewer and p.same_tolerance))


def reason(p: Pair) -> str:
    """Why a pair is not 'fewer evaluations at the same tolerance', from its counts."""
    if not p.fewer:
        other_fd = p.fd.nfev - p.fd.jacobian_columns
        return (
            f"At {p.case}, {p.integrator}, rtol {p.rtol:.0e}, scipy's {p.fd.njev} finite-difference Jacobians "
            f"cost only {p.fd.jacobian_columns} of {p.fd.nfev} evaluations "
            f"({100 * p.fd.jacobian_columns / p.fd.nfev:.1f}%, all an analytic Jacobian can save), while the "
            f"analytic run took {p.analytic.steps} steps against {p.fd.steps} and "
            f"{p.analytic.nfev - other_fd:+d} stage and Newton evaluations."
        )
    return (
        f"At {p.case}, {p.integrator}, rtol {p.rtol:.0e}, the errors differ by more than {SAME_ERROR:g}x "
        f"({sci(p.fd_error)} against {sci(p.analytic_error)})."
    )


def jacobian_markdown(res: ForwardResults) -> list[str]:
    """The report section: the table of pairs and the verdict."""
    ps = pairs(res)
    L = [
        "",
        "### Implicit integrators: analytic against finite-difference Jacobians",
        "",
        "Radau and BDF need df/dy of f = [qd, qdd]. scipy estimates it by finite differences of the vectorised "
        "right-hand side (2 dof columns per Jacobian, counted in RHS evals); the analytic Jacobian "
        "(`models.simulation.simulate.make_jacobian`) is [[0, I], [dqdd/dq + M^-1 dtau/dq, dqdd/dqd + M^-1 dtau/dqd]] "
        "from `model.derivatives` (the analytic derivatives of the Newton-Euler passes with the implicit-function "
        "theorem, `models/derivatives.py`; the equations of motion are unique, so they are the derivatives of "
        "Pinocchio's M and h too) and the controls' own derivatives, and costs no RHS evaluation, so it is "
        "re-evaluated after every accepted step (`models/simulation/forward_dynamics.py`; scipy's own rule, made for "
        "finite differences, holds a Jacobian until Newton converges slowly or fails, and an older Jacobian costs "
        "Newton iterations, at tight tolerances more than the finite-difference Jacobians cost). Same case, "
        "integrator, rtol and atol; the error of the round trip is against the prescribed motion, that of the "
        "stiff case against the Radau reference. 'Same tolerance' means both runs finished and their errors "
        f"agree within {SAME_ERROR:g}x.",
        "",
    ]
    if res.analytic_notes:
        L += [f"- {n}" for n in res.analytic_notes] + [""]
    if not ps:
        return L + ["No analytic runs in this report."]
    L += [
        verdict(ps),
        "",
        f"{TABLE_HEAD} of them in FD Jacobians | RHS evals analytic | saved | "
        "Jacobians FD / analytic | steps FD / analytic | seconds FD / analytic | error FD | error analytic | "
        "same tolerance, fewer evals |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for p in ps:
        if not p.both_ok:
            L.append(
                f"| {p.case} | {p.integrator} | {p.rtol:.0e} | {p.fd.status} | | {p.analytic.status} | | | | | | | no |"
            )
            continue
        L.append(
            f"| {p.case} | {p.integrator} | {p.rtol:.0e} | {p.fd.nfev} | {p.fd.jacobian_columns} | {p.analytic.nfev} | "
            f"{100 * (1 - p.analytic.nfev / p.fd.nfev):.0f}% | {p.fd.njev} / {p.analytic.njev} | "
            f"{p.fd.steps} / {p.analytic.steps} | {p.fd.seconds:.2f} / {p.analytic.seconds:.2f} | "
            f"{sci(p.fd_error)} | {sci(p.analytic_error)} | "
            f"{'yes' if p.fewer and p.same_tolerance else '**no**'} |"
        )
    L += [
        "",
        "Seconds are one run on a shared machine: the analytic Jacobian is one call of the "
        "forward-dynamics derivatives and one LU factorisation per Jacobian, in Python; its gain shows in the "
        "evaluation count.",
    ]
    return L


_e = sci  # one formatter for every report cell (bench.reporting.sci)


def forward_markdown(res: ForwardResults) -> str:
    p = res.profile
    L = [
        "## Forward dynamics",
        "",
        "`M(q) qdd + h(q, qd) = tau` solved for qdd (`models.forward_dynamics`): Pinocchio's M and h from CRBA and "
        "`nonLinearEffects` (its ABA refuses the URDF's mimic joints), other methods' from the functions they "
        "expose or, exactly, from their inverse dynamics (it is linear in qdd: h = ID(q, qd, 0), M e_k = "
        "ID(q, 0, e_k) - ID(q, 0, 0), one batched call per evaluation). The solve is equilibrated by diag(M). "
        "Integration: scipy `solve_ivp`, RK45 and DOP853 (explicit), Radau and BDF (implicit, Jacobian "
        "estimated by scipy from the vectorised right-hand side unless marked analytic, see below); "
        f"atol = {ATOL_FACTOR:g} * rtol.",
        "",
        "### Each method's M and h against CRBA",
        "",
        "| mechanism | method | M and h | max rel. diff M | max rel. diff h | seconds (4 states) |",
        "|---|---|---|---|---|---|",
    ]
    for r in res.terms:
        if r.status != "ok":
            L.append(f"| {r.mechanism} | {r.method} | {r.source} | {r.status} | | |")
        else:
            L.append(f"| {r.mechanism} | {r.method} | {r.source} | {_e(r.m_rel)} | {_e(r.h_rel)} | {r.seconds:.3f} |")
    L += [
        "",
        "### Singular configurations",
        "",
        "| configuration | inverse dynamics | forward dynamics |",
        "|---|---|---|",
    ]
    L += [f"| {s.case} | {s.inverse} | {s.forward} |" for s in res.singular]
    for name, why in res.refused:
        L += [
            "",
            f"**Round trip on the {name} is refused: {why}.** The trunk of eq. (26) stands exactly "
            "vertical (psi5 = pi/2) at every instant: its azimuth is undefined, M is singular, so the spatial gait "
            "has inverse dynamics but no forward dynamics in the paper's coordinates. The round trip below uses "
            "the planar gait and random motions instead.",
        ]
    L += [
        "",
        "### Round trip: controls from inverse dynamics reproduce the prescribed motion",
        "",
        "Controls tau(t) = ID_pinocchio(q*(t), qd*(t), qdd*(t)), evaluated on the fly at every time the integrator "
        "asks for (no interpolation), drive the forward dynamics from (q*(0), qd*(0)); the deviation is "
        "measured at every accepted step, max over time and coordinates (rad or m).",
        "",
        f"**Tolerance.** {ROUND_TRIP_RULE}",
        "",
        "The a priori column is the first-order worst case sum_k |Phi(t_j, t_k)|_q sqrt(m) (atol + rtol |y_k|) "
        "over the accepted steps (each local error passes scipy's RMS test, so each component is below sqrt(m) "
        "times its scale, and is carried to t_j by the linearised flow Phi, computed from 2 dof perturbed copies). "
        "It always holds and is far from sharp: the error estimators of these methods are pessimistic "
        "(local extrapolation), so the pass rule uses the a posteriori estimate.",
        "",
    ]
    L += ["| case | growth G(H) | description |", "|---|---|---|"]
    L += [f"| {c} | {_e(g)} | {res.cases[c]} |" for c, g in res.growth.items()]
    L += [
        "",
        "| case | integrator | rtol | steps | RHS evals | seconds | deviation from q* | estimate E | floor F | "
        "tolerance 2E + F | a priori bound | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for rt in res.round_trips:
        v = rt.verdict if rt.verdict != "FAIL" else "**FAIL**"
        L.append(
            f"| {rt.case} | {rt.integrator} | {rt.rtol:.0e} | {rt.sim.steps} | {rt.sim.nfev} | "
            f"{rt.sim.seconds:.2f} | {_e(rt.error)} | {_e(rt.estimate)} | {_e(rt.floor)} | "
            f"{_e(rt.tolerance) if math.isfinite(rt.estimate) else ''} | {_e(rt.bound)} | {v} |"
        )
    judged = [rt for rt in res.round_trips if math.isfinite(rt.estimate)]
    npass = sum(rt.passed for rt in judged)
    L += ["", f"**{npass} of {len(judged)} judged round trips pass** (the others have no tighter run in the grid)."]
    if res.method_trips:
        L += [
            "",
            f"Per method: forward dynamics from each method's M and h (DOP853, rtol {p.method_rtol:.0e}, "
            f"estimate from rtol {p.method_rtol / TIGHTER:.0e}), the same controls (Pinocchio's inverse dynamics), "
            "so a method passes only if its M and h agree with Pinocchio's RNEA:",
            "",
            "| case | method | steps | seconds | deviation from q* | estimate E | tolerance | verdict |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for rt in res.method_trips:
            if not rt.sim.ok:
                L.append(f"| {rt.case} | {rt.method} | | | | | | {rt.sim.status} |")
                continue
            v = rt.verdict if rt.verdict != "FAIL" else "**FAIL**"
            L.append(
                f"| {rt.case} | {rt.method} | {rt.sim.steps} | {rt.sim.seconds:.2f} | {_e(rt.error)} | "
                f"{_e(rt.estimate)} | {_e(rt.tolerance)} | {v} |"
            )
    L += [
        "",
        "### Conservative case: energy drift",
        "",
        "No actuators; the rods carry springs F = -k (l - l*) with no damping (without them the free telescopes "
        "collapse to l = 0, where M is singular, or extend without bound), so E = T + Pi + sum k/2 (l - l*)^2 "
        "(`models.kinematics.total_energy` plus the springs) is conserved by the exact flow.",
        "",
        "**Tolerance.** E(y_k) - E(y_k-1) = E(y_k) - E(flow(y_k-1)) ~ dE/dy . l_k with l_k the local error of step "
        "k: the drift is a sum of local errors weighted by the energy gradient and is never amplified (E is a "
        "first integral). With |l_k,i| <= sqrt(m) (atol + rtol |y_k,i|) (scipy's RMS test), the bound is "
        "sum_k |dE/dy(y_k)| . sqrt(m) (atol + rtol |y_k|), computed along the run (gradient by central "
        "differences).",
        "",
        "| case | integrator | rtol | steps | seconds | max drift (J) | drift / max T | bound (J) | verdict |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for en in res.energy:
        v = ("pass" if en.passed else "**FAIL**") if en.sim.ok else en.sim.status
        L.append(
            f"| {en.case} | {en.integrator} | {en.rtol:.0e} | {en.sim.steps} | {en.sim.seconds:.2f} | {_e(en.drift)} | "
            f"{_e(en.drift / en.scale if en.scale else math.nan)} | {_e(en.bound)} | {v} |"
        )
    L += [
        "",
        f"### Stiff rods and tiny masses (rtol {p.stiff_rtol:.0e}, at most {p.stiff_budget} right-hand-side "
        f"evaluations or {p.stiff_seconds:g} s per run)",
        "",
        "Rods on critically damped springs (c_i = 2 sqrt(k mu_ii), so the rod modes decay at sqrt(k / mu_ii) without "
        "ringing) in a hanging three-link chain released from rest; tiny masses on the last link at k = 1e4 give "
        f"the same stiffness through the mass. The error is |q(H) - q_ref(H)| against Radau at rtol "
        f"{p.stiff_reference_rtol:.0e}. The "
        "dampers only dissipate, so E = T + Pi + springs never rises along the exact flow: a positive "
        "`max E - E(0)` can only be integration error.",
        "",
        "| case | fastest rod rate (1/s) | cond(M) at start | integrator | status | RHS evals | steps | Jacobians | "
        "LU | seconds | error at H | max E - E(0) (J) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for sr in res.stiff:
        st = "solved" if sr.solved else f"**{sr.sim.status}**"
        L.append(
            f"| {sr.case} | {sr.stiffness:.1e} | {_e(sr.cond)} | {sr.integrator} | {st} | {sr.sim.nfev} | "
            f"{sr.sim.steps} | {sr.sim.njev} | {sr.sim.nlu} | {sr.sim.seconds:.2f} | {_e(sr.error)} | "
            f"{_e(sr.energy_change)} |"
        )
    if res.stiff_notes:
        L += [""] + [f"- {n}" for n in res.stiff_notes]
        L += [
            "",
            "A reference that does not finish at a tight tolerance is itself a finding: where cond(M) is large "
            "(tiny masses), the right-hand side is accurate to about cond(M) * eps only, below which the error "
            "estimates of the implicit integrators are noise and their steps collapse.",
        ]
    expl = [r for r in res.stiff if r.integrator in fd.EXPLICIT]
    impl = [r for r in res.stiff if r.integrator in fd.IMPLICIT]
    if expl and impl:
        stiffest = max(r.stiffness for r in res.stiff)
        e_max = max(r.sim.nfev for r in expl if r.stiffness == stiffest)
        i_max = max(r.sim.nfev for r in impl if r.stiffness == stiffest)
        L += [
            "",
            f"At the stiffest variant ({stiffest:.1e} 1/s) the explicit integrators used up to {e_max} "
            f"evaluations{' (or gave up)' if any(not r.solved for r in expl) else ''}, the implicit ones at most "
            f"{i_max}: explicit step sizes are bounded by stability (h ~ 3 / rate), implicit ones by accuracy.",
        ]
    L += jacobian_markdown(res)
    return "\n".join(L) + "\n"
