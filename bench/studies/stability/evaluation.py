"""Stability study, the evaluation: every method on every case against the 50-digit reference, the
mass matrix's condition number and exact singularities, verdicts and warnings.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field
import math
import time
import warnings

import numpy as np

from exo_bench.api import PreparedSet
from exo_bench.bench.studies.stability.cases import (
    COND_ILL,
    COND_SINGULAR,
    Case,
    FAMILIES,
    IllConditionedWarning,
    Profile,
    REL_DEGRADED,
    REL_UNUSABLE,
)
from exo_bench.bench.studies.study import UnusableMethodWarning
from exo_bench.bench.studies.study import one_line
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.mechanism.singularity import singular_reasons
from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.runtime.prepared import PreparedModel


def reference_forces(mech: Mechanism, q, qd, qdd) -> tuple[np.ndarray, str]:
    """``(tau, label)`` from the 50-digit reference.

    ``bench.reference.reference`` (Lagrange in mpmath where its derivation fits a budget, else
    d'Alembert in mpmath) when importable, else ``lagrange.reference`` directly, else Pinocchio
    as a labelled stand-in (float64, not a 50-digit reference).
    """
    why = ""
    try:
        from exo_bench.bench.studies.study import reference

        return reference(mech, q, qd, qdd)
    except ImportError as e:
        why = one_line(e)
    except Exception as e:  # noqa: BLE001
        why = getattr(e, "skip_reason", None) or one_line(e)
    try:
        from exo_bench.lagrange.high_precision import inverse_dynamics as lref

        return lref(mech, q, qd, qdd, dps=50), "Lagrange, mpmath 50 digits"
    except ImportError as e:
        why = why or one_line(e)
    except Exception as e:  # noqa: BLE001
        why = getattr(e, "skip_reason", None) or one_line(e)
    from exo_bench.models.engines.pinocchio_backend import inverse_dynamics

    return inverse_dynamics(mech, q, qd, qdd), f"pinocchio (float64 stand-in: {why})"


@dataclass
class MethodRow:
    method: str
    status: str = "ok"  # ok, skipped, failed, missing
    reason: str = ""
    abs_err: float = math.nan  # max |tau - ref| over finite entries
    rel_err: float = math.nan  # abs_err / max |ref|
    nonfinite: int = 0
    seconds: float = math.nan

    @property
    def verdict(self) -> str:
        if self.status != "ok":
            return self.status
        if self.nonfinite or not self.rel_err <= REL_UNUSABLE:
            return "unusable"
        return "degraded" if self.rel_err > REL_DEGRADED else "ok"


@dataclass
class CaseResult:
    case: Case
    reference: str
    rows: dict[str, MethodRow]
    cond_raw: float  # max over samples
    cond_eq: float
    cond_mu: float  # cond(D^-1/2 mu D^-1/2): what cond_eq is in exact arithmetic
    singular: list[str]  # exact causes, "sample s: ..." (at most a few)
    singular_samples: int

    @property
    def fd_verdict(self) -> str:
        if self.singular_samples:
            return "singular"
        if not self.cond_raw < COND_SINGULAR:
            return "numerically singular"
        if self.cond_raw >= COND_ILL:
            return "ill-conditioned"
        return "ok"


_VERDICT_ORDER = {"ok": 0, "degraded": 1, "unusable": 2, "skipped": -1, "failed": 3, "missing": -2}


_FD_ORDER = {"ok": 0, "ill-conditioned": 1, "numerically singular": 2, "singular": 3}


def _memo_skip(memo: dict, method: str, mech: Mechanism) -> str | None:
    """The reason to skip ``method`` on ``mech`` without trying: it went over its budget on a model of
    the same structure, or of the same dimension with no more links (the symbolic work grows with n)."""
    for (m, dim, parent, sign), (nlinks, reason) in memo.items():
        if m == method and dim == mech.dim and ((parent, sign) == (mech.parent, mech.sign) or mech.nlinks >= nlinks):
            return reason
    return None


def evaluate_case(
    case: Case, methods: list[str], memo: dict | None = None, models: PreparedSet | None = None
) -> CaseResult:
    """Every method on one case, against the reference; the mass matrix's condition and exact
    singularities. ``memo`` carries skips across cases: a method over its budget on a mechanism
    is not tried again on one of the same structure or with at least as many links in the same
    dimension (the symbolic work is the same or larger)."""
    memo = {} if memo is None else memo
    models = PreparedSet() if models is None else models
    mech = case.mechanism
    ref, label = reference_forces(mech, case.q, case.qd, case.qdd)
    scale = float(np.abs(ref).max())
    rows = {}
    for m in methods:
        row = MethodRow(m)
        known = _memo_skip(memo, m, mech) or predicted_skip(m, mech, models)
        if known:
            row.status, row.reason = "skipped", known
            rows[m] = row
            continue
        model: PreparedModel | Exception  # a failure to prepare is raised in the method's own try below
        try:
            model = models(mech, m)
        except ImportError as e:
            row.status, row.reason = "missing", one_line(e)
            rows[m] = row
            continue
        except Exception as e:  # noqa: BLE001 - over budget while preparing: handled below
            model = e
        try:
            if isinstance(model, Exception):
                raise model
            t0 = time.perf_counter()
            with np.errstate(all="ignore"):
                tau = np.asarray(model.inverse_dynamics(case.q, case.qd, case.qdd), dtype=float)
            row.seconds = time.perf_counter() - t0
            if tau.shape != ref.shape:
                raise ValueError(f"returned shape {tau.shape}, expected {ref.shape}")
        except Exception as e:  # noqa: BLE001 - a failing method is a result, not a crash
            skip = getattr(e, "skip_reason", None)
            if skip:
                row.status, row.reason = "skipped", str(skip)
                memo[(m, mech.dim, mech.parent, mech.sign)] = (
                    mech.nlinks,
                    f"{skip} (on {mech.name}; not retried on the same structure or on "
                    f"{mech.dim}D models of {mech.nlinks} links or more)",
                )
            else:
                row.status, row.reason = "failed", one_line(e)
            rows[m] = row
            continue
        finite = np.isfinite(tau)
        row.nonfinite = int((~finite).sum())
        err = np.where(finite, np.abs(tau - ref), 0.0)
        row.abs_err = float(err.max()) if finite.any() else math.nan
        row.rel_err = row.abs_err / scale if scale > 0 else (0.0 if row.abs_err == 0 else math.inf)
        rows[m] = row
    M = models(mech, "pinocchio").mass_matrix(case.q)
    raw, eq = fd.condition_numbers(M)
    reasons = singular_reasons(mech, case.q)
    flat = [f"sample {s}: {r}" for s, rs in enumerate(reasons) for r in rs]
    return CaseResult(
        case,
        label,
        rows,
        float(raw.max()),
        float(eq.max()),
        equilibrated_mu_condition(mech),
        flat[:3],
        sum(1 for rs in reasons if rs),
    )


def equilibrated_mu_condition(mech: Mechanism) -> float:
    """``cond(D^-1/2 mu D^-1/2)``, ``D = diag(mu)``: the equilibrated condition number of M at every
    configuration where M is regular (see :func:`exo_bench.models.simulation.forward_dynamics.condition_numbers`)."""
    mu = coupling(mech)
    dg = np.diag(mu)
    if (dg <= 0).any():
        return math.inf
    r = 1.0 / np.sqrt(dg)
    return float(np.linalg.cond(mu * r[:, None] * r[None, :]))


@dataclass
class FamilyResult:
    name: str
    doc: str
    results: list[CaseResult]
    seconds: float
    warnings: dict[str, str] = field(default_factory=dict)  # method -> why it is unusable here
    mass_warning: str = ""

    def worst(self, method: str) -> tuple[str, MethodRow | None, CaseResult | None]:
        """The worst verdict of a method over the family, its row and case."""
        best: tuple[str, MethodRow | None, CaseResult | None] = ("missing", None, None)
        rank = -3
        for cr in self.results:
            row = cr.rows.get(method)
            if row is None:
                continue
            v = row.verdict
            r = _VERDICT_ORDER[v]
            worst_row = best[1]  # set whenever r == rank (no verdict ranks -3)
            if r > rank or (
                r == rank
                and v in ("ok", "degraded", "unusable")
                and worst_row is not None
                and (row.nonfinite, row.rel_err) > (worst_row.nonfinite, worst_row.rel_err)
            ):
                best, rank = (v, row, cr), r
        return best

    def fd_worst(self) -> str:
        return max((cr.fd_verdict for cr in self.results), key=_FD_ORDER.__getitem__, default="ok")


def evaluate_family(
    name: str,
    cases: list[Case],
    methods: list[str],
    memo: dict | None = None,
    doc: str = "",
    options: dict[str, dict] | None = None,
) -> FamilyResult:
    """Evaluate every case; warn (:class:`UnusableMethodWarning`, :class:`IllConditionedWarning`)
    once per unusable method and once for an ill-conditioned or singular family."""
    t0 = time.perf_counter()
    memo = {} if memo is None else memo
    # One set of prepared models per case: the cases' mechanisms differ, and large Pinocchio models
    # (n = 100) are released before the next case.
    res = FamilyResult(name, doc, [evaluate_case(c, methods, memo, PreparedSet(options)) for c in cases], 0.0)
    res.seconds = time.perf_counter() - t0
    for m in methods:
        bad = [cr for cr in res.results if m in cr.rows and cr.rows[m].verdict == "unusable"]
        if bad:
            nan = sum(cr.rows[m].nonfinite for cr in bad)
            worst = max(bad, key=lambda cr: (cr.rows[m].nonfinite, cr.rows[m].rel_err))
            msg = (
                f"method {m!r} is unusable on {name}: {len(bad)} of {len(res.results)} cases "
                f"({nan} NaN/Inf values; worst: {worst.case.label}, "
                f"{_nan_or_rel(worst.rows[m])})"
            )
            res.warnings[m] = msg
            warnings.warn(msg, UnusableMethodWarning, stacklevel=2)
    fdw = res.fd_worst()
    if fdw != "ok":
        counts = {v: sum(cr.fd_verdict == v for cr in res.results) for v in _FD_ORDER if v != "ok"}
        parts = ", ".join(f"{c} {v}" for v, c in sorted(counts.items(), key=lambda kv: -_FD_ORDER[kv[0]]) if c)
        first = next(cr for cr in res.results if cr.fd_verdict == fdw)
        msg = (
            f"mass matrix on {name}: {parts} of {len(res.results)} cases (forward dynamics undefined where "
            f"singular, losing digits elsewhere; worst first at {first.case.label}: "
            f"{first.singular[0] if first.singular else f'cond(M) {first.cond_raw:.1e}'})"
        )
        res.mass_warning = msg
        warnings.warn(msg, IllConditionedWarning, stacklevel=2)
    return res


def _nan_or_rel(row: MethodRow) -> str:
    if row.nonfinite:
        return f"{row.nonfinite} NaN/Inf"
    return f"relative error {row.rel_err:.1e}"


# ----------------------------------------------------------------------------- run
#: A lagrange derivation predicted within the profile's budget runs with this many times the budget:
#: on a loaded machine it finishes rather than turning its row into a skip. Which rows skip is the
#: cost model's prediction alone (:func:`predicted_skip`), the same on every machine.
LOAD_ALLOWANCE = 10.0


def method_options(profile: Profile) -> dict[str, dict]:
    """The :func:`prepare` options of the profile: ``lagrange``'s derivation budget, the profile's
    times :data:`LOAD_ALLOWANCE` (the skip itself is decided by :func:`predicted_skip`)."""
    return {"lagrange": {"budget": LOAD_ALLOWANCE * profile.lagrange_budget}}


def predicted_skip(method: str, mech: Mechanism, models: PreparedSet) -> str | None:
    """Why ``method`` is skipped on ``mech`` before any work: its derivation predicted (the cost
    model, exo_bench/api/cost_model.py) over the profile's budget (``models``' budget over
    :data:`LOAD_ALLOWANCE`); None when it is not a derivation or fits."""
    budget = models.options.get(method, {}).get("budget")
    from exo_bench.api.methods import derives_within_budget

    if not derives_within_budget(method) or budget is None:
        return None
    from exo_bench.api.cost_model import estimate

    predicted, allowed = estimate(mech, method).setup_seconds, float(budget) / LOAD_ALLOWANCE
    if predicted <= allowed:
        return None
    return (
        f"its derivation is predicted to take {predicted:.3g} s (the cost model), over the profile's budget "
        f"of {allowed:g} s"
    )


def predicted_skips(profile: Profile, method: str = "lagrange") -> dict[str, str]:
    """``mechanism name -> reason`` of every mechanism of the profile's families that
    :func:`predicted_skip` skips (what the report's skipped rows are, on any machine)."""
    models = PreparedSet(method_options(profile))
    out: dict[str, str] = {}
    for make in FAMILIES.values():
        for case in make(profile):
            reason = predicted_skip(method, case.mechanism, models)
            if reason:
                out[case.mechanism.name] = reason
    return out


def evaluate_families(profile: Profile, methods: list[str], log=print) -> list[FamilyResult]:
    memo: dict = {}
    out = []
    for name, make in FAMILIES.items():
        log(f"stability: family {name}")
        doc = " ".join((make.__doc__ or "").split())
        out.append(evaluate_family(name, make(profile), methods, memo, doc, method_options(profile)))
    return out
