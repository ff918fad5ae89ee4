"""Forward-dynamics study: the implicit integrators with the analytic Jacobian against scipy's
finite differences, the report section.

Radau and BDF need ``df/dy`` of the right-hand side ``f = [qd, qdd]``. scipy estimates it by finite
differences of the vectorised right-hand side: ``2 dof`` more evaluations per Jacobian (counted in
``RHS evals``, which counts columns). The analytic Jacobian
(:func:`exo_bench.models.simulation.forward_dynamics.make_jacobian`) comes from the forward-dynamics derivatives of
``model.derivatives`` (the analytic derivatives of the Newton-Euler passes,
:mod:`exo_bench.models.derivatives.derivatives`; issue 36, before it CasADi's differentiation of the factored closed
forms) and the controls' own derivatives, and costs no right-hand-side
evaluation, so it is re-evaluated after every accepted step (:mod:`exo_bench.models.simulation.implicit_integrators`).
Each analytic run is paired with the finite-difference run of the same case,
integrator and tolerance (:func:`pairs`), and the report says whether it reached the same
tolerance in fewer evaluations (:func:`verdict`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from exo_bench.bench.output.provenance import sci
from exo_bench.bench.studies.stability.forward_evaluation import ForwardResults

if TYPE_CHECKING:
    from exo_bench.models.simulation.simulate import Simulation


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
        "(`models.forward_dynamics.make_jacobian`) is [[0, I], [dqdd/dq + M^-1 dtau/dq, dqdd/dqd + M^-1 dtau/dqd]] "
        "from `model.derivatives` (the analytic derivatives of the Newton-Euler passes with the implicit-function "
        "theorem, `models/derivatives/derivatives.py`; the equations of motion are unique, so they are the derivatives of "
        "Pinocchio's M and h too) and the controls' own derivatives, and costs no RHS evaluation, so it is "
        "re-evaluated after every accepted step (`models/simulation/implicit_integrators.py`; scipy's own rule, made for "
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
