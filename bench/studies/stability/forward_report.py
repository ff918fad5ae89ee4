"""Forward-dynamics study, the report: its sections of ``reports/stability.md``."""

from __future__ import annotations

import math

from exo_bench.bench.output.provenance import sci
from exo_bench.bench.studies.stability.forward_cases import ATOL_FACTOR, ROUND_TRIP_RULE, TIGHTER
from exo_bench.bench.studies.stability.forward_evaluation import ForwardResults
from exo_bench.bench.studies.stability.forward_jacobian import jacobian_markdown
from exo_bench.models.simulation import forward_dynamics as fd


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
