"""``exo-bench stability``: where each method breaks, and the forward-dynamics round trip.

A benign baseline and six families of extreme cases (:data:`FAMILIES`), each a list of
:class:`Case` (a mechanism and states). For every case and every method registered in :data:`bench.methods.METHODS` *at run
time*, the report gives the largest absolute and relative error against the 50-digit reference,
the number of NaN/Inf values, and the condition number of the mass matrix; a method that is
missing, over its time budget or raising is recorded as such (one line), never a crash.

Verdicts and their thresholds (justified in the report, see :func:`thresholds_markdown`):

* inverse dynamics of a method on a case is **unusable** when it returns any NaN/Inf or its
  relative error exceeds :data:`REL_UNUSABLE`, **degraded** above :data:`REL_DEGRADED`; an
  unusable method raises :class:`UnusableMethodWarning` and a bold line in the report;
* the mass matrix (forward dynamics) is **singular** where :func:`models.forward_dynamics.
  singular_reasons` finds an exact cause (vertical rod, zero length, massless link),
  **numerically singular** when ``cond(M) >= COND_SINGULAR`` and **ill-conditioned** when
  ``cond(M) >= COND_ILL`` (:class:`IllConditionedWarning`).

The forward-dynamics part (round trip, energy drift, stiff rods, work-precision diagrams) lives
in :mod:`bench.forward`; :func:`run` writes both into ``reports/stability.md`` with its PNGs.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from exo_bench.bench.methods import PreparedSet
from exo_bench.bench.study import one_line
from exo_bench.models import forward_dynamics as fd
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.motion import GaitParams, gait, planar_gait, random_states
from exo_bench.models.presets import chain, exo5, random_tree

EPS = float(np.finfo(float).eps)

#: Relative error (max |tau - ref| / max |ref|) above which a method is unusable on a case.
REL_UNUSABLE = 1e-6
#: Relative error above which a method is degraded (still usable, digits lost).
REL_DEGRADED = 1e-9
#: cond(M) (2-norm, SI units) from which forward dynamics is ill-conditioned.
COND_ILL = 1e6
#: cond(M) from which forward dynamics is numerically singular.
COND_SINGULAR = 1e12


from exo_bench.bench.study import StabilityWarning, UnusableMethodWarning  # noqa: E402 (re-exported)


class IllConditionedWarning(StabilityWarning):
    """A family's mass matrix is ill-conditioned or singular: forward dynamics loses digits or is
    undefined there."""


# ----------------------------------------------------------------------------- profiles
@dataclass(frozen=True)
class Profile:
    name: str
    samples: int                          # states per case
    distances: tuple[float, ...]          # from pi/2 (vertical rods) and from eq. (18)'s singularities
    lengths: tuple[float, ...]            # scale of every rod
    one_length: tuple[float, ...]         # length of link 2 alone
    ratios: tuple[float, ...]             # mass ratio swing leg / rest
    large_n: tuple[int, ...]
    periods: tuple[float, ...]            # gait period T (s)
    lagrange_budget: float                # seconds of symbolic work per mechanism for `lagrange`
    wp_rtols: tuple[float, ...]           # round-trip work-precision grid (gait), every integrator
    rt_rtols: tuple[float, ...]           # the other round-trip cases (DOP853 and Radau)
    rt_integrators: tuple[str, ...]       # integrators of the other round-trip cases
    method_rtol: float                    # per-method round trip (DOP853)
    energy_rtols: tuple[float, ...]
    stiff_k: tuple[float, ...]
    stiff_mass_scales: tuple[float, ...]  # tiny masses, at k = 1e4
    stiff_rtol: float
    stiff_budget: int                     # right-hand-side evaluations before an integrator gives up
    full_cases: bool = False
    method_seconds: float = 120.0         # wall time per method per forward-dynamics run
    rt_cases: tuple[str, ...] = ()        # round-trip cases to run (empty: all of bench.forward.round_trip_cases)
    method_cases: tuple[str, ...] = ("exo5-2d planar gait", "tree4-3d random motion")  # every method's M, h
    energy_cases: tuple[str, ...] = ()    # conservative cases to run (empty: all)
    stiff_reference_rtol: float = 1e-9    # Radau reference of the stiff runs
    stiff_seconds: float = 30.0           # wall time per stiff run (and its reference)


QUICK = Profile("quick", samples=3, distances=(1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 0.0),
                lengths=(0.0, 1e-9, 1e-6, 1e-3, 1.0, 1e3, 1e6), one_length=(0.0, 1e-9, 1e-6, 1e-3, 1e3, 1e6),
                ratios=(1e-6, 1e-3, 1.0, 1e3, 1e6), large_n=(50, 100), periods=(1.1, 0.1, 0.01),
                lagrange_budget=10.0, wp_rtols=(1e-4, 1e-6, 1e-8, 1e-10, 1e-12), rt_rtols=(1e-6, 1e-8, 1e-10),
                rt_integrators=("DOP853", "Radau"), method_rtol=1e-8, energy_rtols=(1e-5, 1e-7, 1e-9),
                stiff_k=(1e4, 1e6, 1e8), stiff_mass_scales=(1e-4,), stiff_rtol=1e-6, stiff_budget=20_000,
                method_seconds=60.0)
FULL = Profile("full", samples=8, distances=(1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10,
                                             1e-11, 1e-12, 1e-13, 0.0),
               lengths=(0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1e-1, 1.0, 10.0, 1e3, 1e6),
               one_length=(0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1e3, 1e6),
               ratios=(1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0, 1e2, 1e3, 1e4, 1e5, 1e6),
               large_n=(50, 100), periods=(1.1, 0.5, 0.3, 0.1, 0.03, 0.01, 0.003), lagrange_budget=120.0,
               wp_rtols=(1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12),
               rt_rtols=(1e-6, 1e-8, 1e-10, 1e-12), rt_integrators=("RK45", "DOP853", "Radau", "BDF"),
               method_rtol=1e-10, energy_rtols=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10),
               stiff_k=(1e3, 1e4, 1e5, 1e6, 1e7, 1e8), stiff_mass_scales=(1e-2, 1e-4, 1e-6), stiff_rtol=1e-6,
               stiff_budget=200_000, full_cases=True, method_seconds=600.0, stiff_seconds=120.0)


# ----------------------------------------------------------------------------- cases
@dataclass(frozen=True, eq=False)
class Case:
    """A scene-like extreme case: a mechanism and states ``(samples, dof)``."""

    family: str
    series: str                 # sub-series within the family (one line in the plots)
    label: str                  # this case within the series
    x: float                    # the swept parameter (distance, length, ratio, n, T)
    mechanism: Mechanism
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


def _fmt(x: float) -> str:
    return "0" if x == 0 else f"{x:.0e}"


BASELINE = "benign baseline (control)"


def family_baseline(p: Profile) -> list[Case]:
    """Seeded random states of the paper's models and of random trees, away from every singularity
    (elevations within 1.2 rad of the horizontal, lengths 0.3 .. 1.2 m): the level every method
    reaches when nothing is extreme. A method unusable here is wrong, not unstable."""
    out = []
    for k, mech in enumerate((exo5(3), exo5(2), random_tree(6, 3, 1), random_tree(6, 2, 2))):
        q, qd, qdd = random_states(mech, p.samples, 50 + k)
        out.append(Case(BASELINE, "baseline", mech.name, math.nan, mech, q, qd, qdd))
    return out


def family_near_vertical(p: Profile) -> list[Case]:
    """exo5-3d with every elevation at ``pi/2 - d`` (vertical rods; the gait of eq. 26 lives
    there, its trunk exactly at pi/2), azimuths, lengths, rates random (seeded)."""
    mech = exo5(3)
    n = mech.nlinks
    out = []
    for k, d in enumerate(p.distances):
        q, qd, qdd = random_states(mech, p.samples, 100 + k)
        q[:, n:2 * n] = math.pi / 2 - d
        out.append(Case("near-vertical rods", "psi = pi/2 - d", f"d = {_fmt(d)}", d, mech, q, qd, qdd))
    return out


def family_removable(p: Profile) -> list[Case]:
    """exo5-3d at the removable singularities of eq. (18) and at distance ``d`` from them:
    ``cos(phi_i - phi_j) = 0`` (consecutive azimuths pi/2 + d apart), ``cos phi_i = 0``
    (``phi_i = +-pi/2 + d``), ``sin phi_i = 0`` (``phi_i = d``; exactly 0 at d = 0)."""
    mech = exo5(3)
    n = mech.nlinks
    out = []
    for k, d in enumerate(p.distances):
        for series, seed in (("cos(phi_i - phi_j) = 0", 200), ("cos phi_i = 0", 300), ("sin phi_i = 0", 400)):
            q, qd, qdd = random_states(mech, p.samples, seed + k)
            rng = np.random.default_rng(seed + k)
            if series.startswith("cos(phi_i"):
                q[:, :n] = q[:, :1] + np.arange(n) * (math.pi / 2 + d)
            elif series.startswith("cos phi"):
                q[:, :n] = rng.choice([-1.0, 1.0], (p.samples, n)) * math.pi / 2 + d
            else:
                q[:, :n] = d
            out.append(Case("removable singularities of eq. (18)", series, f"{series}, d = {_fmt(d)}", d,
                            mech, q, qd, qdd))
    return out


def family_lengths(p: Profile) -> list[Case]:
    """exo5-3d with every rod scaled to ``L * U(0.5, 1.5)``, and with link 2 alone at length ``L``."""
    mech = exo5(3)
    n = mech.nlinks
    out = []
    for k, L in enumerate(p.lengths):
        q, qd, qdd = random_states(mech, p.samples, 500 + k)
        rng = np.random.default_rng(500 + k)
        q[:, -n:] = L * rng.uniform(0.5, 1.5, (p.samples, n))
        # Rates of the lengths scale with them, so that the motion stays the same shape.
        qd[:, -n:] *= L
        qdd[:, -n:] *= L
        out.append(Case("very short and very long rods", "every rod ~ L", f"every rod ~ L = {_fmt(L)} m", L,
                        mech, q, qd, qdd))
    for k, L in enumerate(p.one_length):
        q, qd, qdd = random_states(mech, p.samples, 600 + k)
        q[:, mech.dof - n + 1] = L  # l_2
        out.append(Case("very short and very long rods", "link 2 at L", f"l2 = {_fmt(L)} m", L, mech, q, qd, qdd))
    return out


def _scaled(mech: Mechanism, links: tuple[int, ...], r: float, name: str) -> Mechanism:
    masses = [tuple(r * x for x in m) if i in links else m for i, m in enumerate(mech.masses)]
    return mech.replace(masses=tuple(masses), name=name)


def family_masses(p: Profile) -> list[Case]:
    """exo5-3d with the swing leg's masses (links 3 and 4) multiplied by ``r``; with zero middle
    masses; with a massless swing shin (no middle or end mass: its coordinates move nothing)."""
    base = exo5(3)
    out = []
    for k, r in enumerate(p.ratios):
        mech = _scaled(base, (2, 3), r, f"exo5-3d, swing leg masses x{r:g}")
        q, qd, qdd = random_states(mech, p.samples, 700 + k)
        out.append(Case("mass ratios", "swing leg masses x r", f"r = {r:.0e}", r, mech, q, qd, qdd))
    zero_mid = base.replace(masses=tuple((m0, 0.0, m2) for m0, _, m2 in base.masses), name="exo5-3d, no middle masses")
    q, qd, qdd = random_states(zero_mid, p.samples, 790)
    out.append(Case("mass ratios", "special", "zero middle masses", math.nan, zero_mid, q, qd, qdd))
    m = list(base.masses)
    m[3] = (m[3][0], 0.0, 0.0)
    massless = base.replace(masses=tuple(m), name="exo5-3d, massless swing shin")
    q, qd, qdd = random_states(massless, p.samples, 791)
    out.append(Case("mass ratios", "special", "massless swing shin (m41 = m42 = 0)", math.nan, massless, q, qd, qdd))
    return out


def family_large_n(p: Profile) -> list[Case]:
    """Seeded 3D chains and random trees of n = 50 (and 100 in the full profile) links."""
    out = []
    for n in p.large_n:
        for mech in (chain(n, 3, seed=n), random_tree(n, 3, seed=n)):
            q, qd, qdd = random_states(mech, p.samples, 800 + n)
            kind = "chain" if mech.is_chain() else "random tree"
            out.append(Case("large n", kind, f"{kind}, n = {n}", float(n), mech, q, qd, qdd))
    return out


def family_fast_gaits(p: Profile) -> list[Case]:
    """The gait of eq. (26) (exo5-3d) and its planar version (exo5-2d) at periods ``T``, sampled
    over one period: rates grow like 1/T, accelerations like 1/T^2."""
    out = []
    for mech, fn, series in ((exo5(3), gait, "exo5-3d gait (eq. 26)"), (exo5(2), planar_gait, "exo5-2d planar gait")):
        for T in p.periods:
            t = np.linspace(0.0, T, max(p.samples, 4), endpoint=False)
            m = fn(mech, t, GaitParams(T=T))
            out.append(Case("fast gaits", series, f"{series.split()[0]}, T = {T:g} s", T, mech, m.q, m.qd, m.qdd))
    return out


FAMILIES = {
    BASELINE: family_baseline,
    "near-vertical rods": family_near_vertical,
    "removable singularities of eq. (18)": family_removable,
    "very short and very long rods": family_lengths,
    "mass ratios": family_masses,
    "large n": family_large_n,
    "fast gaits": family_fast_gaits,
}


# ----------------------------------------------------------------------------- evaluation


def reference_forces(mech: Mechanism, q, qd, qdd) -> tuple[np.ndarray, str]:
    """``(tau, label)`` from the 50-digit reference.

    ``bench.reference.reference`` (Lagrange in mpmath where its derivation fits a budget, else
    d'Alembert in mpmath) when importable, else ``lagrange.reference`` directly, else Pinocchio
    as a labelled stand-in (float64, not a 50-digit reference).
    """
    why = ""
    try:
        from exo_bench.bench.reference import reference

        return reference(mech, q, qd, qdd)
    except ImportError as e:
        why = one_line(e)
    except Exception as e:  # noqa: BLE001
        why = getattr(e, "skip_reason", None) or one_line(e)
    try:
        from exo_bench.lagrange.reference import inverse_dynamics as lref

        return lref(mech, q, qd, qdd, dps=50), "Lagrange, mpmath 50 digits"
    except ImportError as e:
        why = why or one_line(e)
    except Exception as e:  # noqa: BLE001
        why = getattr(e, "skip_reason", None) or one_line(e)
    from exo_bench.models.pinocchio_backend import inverse_dynamics

    return inverse_dynamics(mech, q, qd, qdd), f"pinocchio (float64 stand-in: {why})"


@dataclass
class MethodRow:
    method: str
    status: str = "ok"                # ok, skipped, failed, missing
    reason: str = ""
    abs_err: float = math.nan         # max |tau - ref| over finite entries
    rel_err: float = math.nan         # abs_err / max |ref|
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
    cond_raw: float                   # max over samples
    cond_eq: float
    cond_mu: float                    # cond(D^-1/2 mu D^-1/2): what cond_eq is in exact arithmetic
    singular: list[str]               # exact causes, "sample s: ..." (at most a few)
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


def evaluate_case(case: Case, methods: list[str], memo: dict | None = None,
                  models: PreparedSet | None = None) -> CaseResult:
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
        known = _memo_skip(memo, m, mech)
        if known:
            row.status, row.reason = "skipped", known
            rows[m] = row
            continue
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
                    mech.nlinks, f"{skip} (on {mech.name}; not retried on the same structure or on "
                                 f"{mech.dim}D models of {mech.nlinks} links or more)")
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
    reasons = fd.singular_reasons(mech, case.q)
    flat = [f"sample {s}: {r}" for s, rs in enumerate(reasons) for r in rs]
    return CaseResult(case, label, rows, float(raw.max()), float(eq.max()), equilibrated_mu_condition(mech),
                      flat[:3], sum(1 for rs in reasons if rs))


def equilibrated_mu_condition(mech: Mechanism) -> float:
    """``cond(D^-1/2 mu D^-1/2)``, ``D = diag(mu)``: the equilibrated condition number of M at every
    configuration where M is regular (see :func:`models.forward_dynamics.condition_numbers`)."""
    mu = fd.mass_distribution_matrix(mech)
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
    warnings: dict[str, str] = field(default_factory=dict)    # method -> why it is unusable here
    mass_warning: str = ""

    def worst(self, method: str) -> tuple[str, MethodRow | None, CaseResult | None]:
        """The worst verdict of a method over the family, its row and case."""
        best = ("missing", None, None)
        rank = -3
        for cr in self.results:
            row = cr.rows.get(method)
            if row is None:
                continue
            v = row.verdict
            r = _VERDICT_ORDER[v]
            if r > rank or (r == rank and v in ("ok", "degraded", "unusable")
                            and (row.nonfinite, row.rel_err) > (best[1].nonfinite, best[1].rel_err)):
                best, rank = (v, row, cr), r
        return best

    def fd_worst(self) -> str:
        return max((cr.fd_verdict for cr in self.results), key=_FD_ORDER.get, default="ok")


def evaluate_family(name: str, cases: list[Case], methods: list[str], memo: dict | None = None,
                    doc: str = "", options: dict[str, dict] | None = None) -> FamilyResult:
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
            msg = (f"method {m!r} is unusable on {name}: {len(bad)} of {len(res.results)} cases "
                   f"({nan} NaN/Inf values; worst: {worst.case.label}, "
                   f"{_nan_or_rel(worst.rows[m])})")
            res.warnings[m] = msg
            warnings.warn(msg, UnusableMethodWarning, stacklevel=2)
    fdw = res.fd_worst()
    if fdw != "ok":
        counts = {v: sum(cr.fd_verdict == v for cr in res.results) for v in _FD_ORDER if v != "ok"}
        parts = ", ".join(f"{c} {v}" for v, c in sorted(counts.items(), key=lambda kv: -_FD_ORDER[kv[0]]) if c)
        first = next(cr for cr in res.results if cr.fd_verdict == fdw)
        msg = (f"mass matrix on {name}: {parts} of {len(res.results)} cases (forward dynamics undefined where "
               f"singular, losing digits elsewhere; worst first at {first.case.label}: "
               f"{first.singular[0] if first.singular else f'cond(M) {first.cond_raw:.1e}'})")
        res.mass_warning = msg
        warnings.warn(msg, IllConditionedWarning, stacklevel=2)
    return res


def _nan_or_rel(row: MethodRow) -> str:
    if row.nonfinite:
        return f"{row.nonfinite} NaN/Inf"
    return f"relative error {row.rel_err:.1e}"


# ----------------------------------------------------------------------------- report: families
def _e(x: float, digits: int = 1) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    if math.isinf(x):
        return "inf"
    return f"{x:.{digits}e}"


def baseline_level(families: list[FamilyResult]) -> tuple[float, list[str]]:
    """The largest relative error on the benign baseline among the methods usable there, and them."""
    base = next((fr for fr in families if fr.name == BASELINE), None)
    if base is None:
        return math.nan, []
    ok = sorted({m for cr in base.results for m, r in cr.rows.items() if r.status == "ok"} - set(base.warnings))
    level = max((cr.rows[m].rel_err for cr in base.results for m in ok if m in cr.rows
                 and math.isfinite(cr.rows[m].rel_err)), default=math.nan)
    return level, ok


def thresholds_markdown(families: list[FamilyResult] | None = None, tightest_rtol: float = 1e-12) -> str:
    eps = EPS
    level, ok = baseline_level(families or [])
    measured = (f"measured here: {', '.join(ok)} stay below {level:.1e} on the {BASELINE}, i.e. within "
                f"{level / eps:.0f} ulp" if ok else "no baseline measured in this run")
    return "\n".join([
        "## Thresholds, and why", "",
        f"- **Inverse dynamics unusable**: any NaN/Inf, or a relative error (max |tau - ref| / max |ref| over the "
        f"case) above **{REL_UNUSABLE:.0e}**. A backward-stable float64 evaluation of these sums is accurate to "
        f"a modest multiple of eps = {eps:.1e} ({measured}); {REL_UNUSABLE:.0e} means that about "
        f"{math.log10(REL_UNUSABLE / eps):.0f} of the 16 significant digits are lost, and it is two orders below the resolution of a good joint torque sensor (assumed 1e-4 of full "
        "scale), so the error would start to show in the controls.",
        f"- **Inverse dynamics degraded**: relative error above **{REL_DEGRADED:.0e}**: still usable for control, "
        "not for cross-validation of implementations at the 1e-12 level.",
        f"- **Forward dynamics ill-conditioned**: cond(M) (2-norm, SI units) at or above **{COND_ILL:.0e}**. "
        f"Every method delivers M to normwise accuracy only (relative to its largest entry; the near-vertical "
        f"rows below show Pinocchio's small entries lost), so qdd is accurate to about cond(M) * eps: "
        f"{COND_ILL * eps:.1e} at the threshold, already above the tightest integrator tolerance of this report "
        f"({tightest_rtol:.0e}): the linear algebra, not the integrator, then limits accuracy. cond(M) also measures the "
        "spread of the inertias, hence of the time scales (frequencies go like 1/sqrt(inertia)): at 1e6 they span "
        "three orders of magnitude and the ODE turns stiff.",
        f"- **Forward dynamics numerically singular**: cond(M) at or above **{COND_SINGULAR:.0e}**: "
        f"cond * eps = {COND_SINGULAR * eps:.1e}, fewer than four correct digits in qdd.",
        "- **Forward dynamics singular**: an exact cause, found without thresholds on a condition number "
        "(`models.forward_dynamics.singular_reasons`): a rod of length 0, a vertical rod (|cos psi| <= "
        f"{fd.COS_VERTICAL:.0e}, i.e. within a few ulp of pi/2: the float nearest pi/2 has cos = 6.1e-17), or a "
        "link whose coordinates move no mass. Inverse dynamics is still defined there; forward dynamics is not, "
        "and `models.forward_dynamics.accelerations` raises `SingularConfigurationError` naming the link.",
        "- **cond_eq** = cond(D^-1/2 M D^-1/2), D = diag(M), is in exact arithmetic the same at every "
        "configuration: cond(mu_s) of the equilibrated mass distribution matrix (column `cond(mu_s)`), because "
        "D^-1/2 M D^-1/2 is orthogonally similar to mu_s (x) I (see `condition_numbers`). Where the computed "
        "cond_eq departs from cond(mu_s), the computed M has lost its small entries.",
        "",
    ])


def _cell(row: MethodRow | None) -> str:
    if row is None:
        return ""
    v = row.verdict
    if row.status != "ok":
        return row.status
    if row.nonfinite:
        return f"**{row.nonfinite} NaN/Inf**"
    txt = _e(row.rel_err)
    return f"**{txt}**" if v == "unusable" else (f"_{txt}_" if v == "degraded" else txt)


def family_summary_markdown(families: list[FamilyResult], methods: list[str]) -> str:
    lines = ["## Summary: every family, every method", "",
             "Worst case of each method over each family, against the 50-digit reference. The relative error of a "
             "case is max |tau - ref| / max |ref| over its samples and coordinates (abs in N m or N); NaN/Inf "
             "entries are counted apart and left out of the errors.", "",
             "| family | method | verdict | cases run | max abs error | max rel error | NaN/Inf | where (worst case) |",
             "|---|---|---|---|---|---|---|---|"]
    for fr in families:
        for m in methods:
            verdict, row, cr = fr.worst(m)
            ran = [c for c in fr.results if m in c.rows and c.rows[m].status == "ok"]
            nan = sum(c.rows[m].nonfinite for c in ran)
            if row is None or row.status != "ok":
                reason = row.reason if row is not None else "not evaluated"
                lines.append(f"| {fr.name} | {m} | {verdict} | {len(ran)}/{len(fr.results)} | | | | {reason} |")
                continue
            amax = max((c.rows[m].abs_err for c in ran if math.isfinite(c.rows[m].abs_err)), default=math.nan)
            rmax = max((c.rows[m].rel_err for c in ran if math.isfinite(c.rows[m].rel_err)), default=math.nan)
            skipped = [c for c in fr.results if m in c.rows and c.rows[m].status != "ok"]
            where = cr.case.label + (f"; skipped/failed on {len(skipped)}: {skipped[0].rows[m].reason}"
                                     if skipped else "")
            vtxt = f"**{verdict}**" if verdict in ("unusable", "failed") else verdict
            lines.append(f"| {fr.name} | {m} | {vtxt} | {len(ran)}/{len(fr.results)} | {_e(amax)} | {_e(rmax)} | "
                         f"{nan} | {where} |")
    lines += ["", "Mass matrix (from Pinocchio's CRBA) over each family:", "",
              "| family | forward dynamics | cases flagged | cond(M) range | cond_eq range | cond(mu_s) range |",
              "|---|---|---|---|---|---|"]
    for fr in families:
        v = fr.fd_worst()
        flagged = [cr for cr in fr.results if cr.fd_verdict != "ok"]
        raws = [cr.cond_raw for cr in fr.results]
        eqs = [cr.cond_eq for cr in fr.results]
        mus = [cr.cond_mu for cr in fr.results]
        rng = lambda xs: f"{_e(min(xs))} .. {_e(max(xs))}"
        vtxt = f"**{v}**" if v != "ok" else v
        lines.append(f"| {fr.name} | {vtxt} | {len(flagged)}/{len(fr.results)} | {rng(raws)} | {rng(eqs)} | {rng(mus)} |")
    return "\n".join(lines) + "\n"


def family_detail_markdown(fr: FamilyResult, methods: list[str]) -> str:
    refs = sorted({cr.reference for cr in fr.results})
    lines = [f"### {fr.name}", "", fr.doc, "",
             f"Reference: {'; '.join(refs)}. {len(fr.results)} cases, {fr.results[0].case.q.shape[0]} or more "
             f"samples each; {fr.seconds:.1f} s. Cells: relative error (bold: unusable, italic: degraded).", "",
             "| case | cond(M) | cond_eq | cond(mu_s) | forward dynamics | " + " | ".join(methods) + " |",
             "|---|---|---|---|---|" + "---|" * len(methods)]
    for cr in fr.results:
        fdv = cr.fd_verdict if cr.fd_verdict == "ok" else f"**{cr.fd_verdict}**"
        lines.append(f"| {cr.case.label} | {_e(cr.cond_raw)} | {_e(cr.cond_eq)} | {_e(cr.cond_mu)} | {fdv} | "
                     + " | ".join(_cell(cr.rows.get(m)) for m in methods) + " |")
    sing = [cr for cr in fr.results if cr.singular]
    if sing:
        lines += ["", "Singular configurations detected (first cause per case):", ""]
        lines += [f"- {cr.case.label}: {cr.singular[0]}" + (f" ({cr.singular_samples} samples)"
                                                              if cr.singular_samples > 1 else "") for cr in sing]
    other = [(cr, m, cr.rows[m]) for cr in fr.results for m in methods
             if m in cr.rows and cr.rows[m].status in ("failed", "missing")]
    if other:
        lines += ["", "Methods that failed or are missing:", ""]
        seen = set()
        for cr, m, row in other:
            if (m, row.reason) not in seen:
                seen.add((m, row.reason))
                lines.append(f"- {m} ({row.status}, first on {cr.case.label}): {row.reason}")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- figures
_MCOLORS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#17becf")
_SERIES_STYLES = ("-", "--", ":", "-.")
FLOOR = 1e-18  # errors of exactly 0 are drawn here on the log axes


def _xpos(xs: np.ndarray) -> np.ndarray:
    """Plot positions on a log axis: 0 (exactly at the singularity) goes two decades below the
    smallest positive value."""
    pos = xs[xs > 0]
    zero_at = (pos.min() / 100.0) if pos.size else 1e-18
    return np.where(xs > 0, xs, zero_at)


_XLABELS = {"near-vertical rods": "d = pi/2 - psi (rad)", "removable singularities of eq. (18)": "distance d (rad)",
            "very short and very long rods": "L (m)", "mass ratios": "r (swing leg masses x r)", "large n": "n",
            "fast gaits": "T (s)"}


def _swept(families: list[FamilyResult]) -> list[FamilyResult]:
    return [fr for fr in families if any(math.isfinite(cr.case.x) for cr in fr.results)]


def _series_title(fr: FamilyResult, series: list[str]) -> str:
    if len(series) < 2:
        return fr.name
    marks = {"-": "solid", "--": "dashed", ":": "dotted", "-.": "dash-dot"}
    return fr.name + "\n" + "; ".join(f"{marks[_SERIES_STYLES[i % 4]]}: {s}" for i, s in enumerate(series))


def _family_panels(families: list[FamilyResult]):
    """A 2 x 3 figure with one panel per swept family (unused panels hidden), and per panel
    ``(ax, family, cases with a finite x, sub-series names, x position of each case by id)``."""
    from matplotlib.figure import Figure

    fams = _swept(families)
    fig = Figure(figsize=(13, 7.2), layout="constrained")
    axes = fig.subplots(2, 3).ravel()
    for ax in axes[len(fams):]:
        ax.set_visible(False)
    panels = []
    for ax, fr in zip(axes, fams):
        cases = [cr for cr in fr.results if math.isfinite(cr.case.x)]
        series = list(dict.fromkeys(cr.case.series for cr in cases))
        allx = _xpos(np.array([cr.case.x for cr in cases]))
        panels.append((ax, fr, cases, series, {id(cr): x for cr, x in zip(cases, allx)}))
    return fig, panels


def families_figure(families: list[FamilyResult], methods: list[str]):
    """Relative error against the swept parameter, one panel per family, one colour per method,
    one line style per sub-series; cases with NaN/Inf are red crosses at 1 (no line point)."""
    fig, panels = _family_panels(families)
    for ax, fr, cases, series, xmap in panels:
        nan_label = True
        for mi, m in enumerate(methods):
            for si, s in enumerate(series):
                crs = sorted([cr for cr in cases if cr.case.series == s and m in cr.rows and cr.rows[m].status == "ok"],
                             key=lambda cr: xmap[id(cr)])
                if not crs:
                    continue
                xs = np.array([xmap[id(cr)] for cr in crs])
                ys = np.array([np.nan if cr.rows[m].nonfinite else max(cr.rows[m].rel_err, FLOOR) for cr in crs])
                ax.loglog(xs, ys, color=_MCOLORS[mi % len(_MCOLORS)], ls=_SERIES_STYLES[si % 4], marker=".",
                          lw=1, label=m if si == 0 else None)
                bad = [i for i, cr in enumerate(crs) if cr.rows[m].nonfinite]
                if bad:
                    ax.scatter(xs[bad], np.full(len(bad), 1.0), marker="x", color=_MCOLORS[mi % len(_MCOLORS)],
                               s=40, zorder=5, label=f"NaN/Inf ({m})" if nan_label else None)
                    nan_label = False
        ax.axhline(REL_UNUSABLE, color="red", lw=0.6, ls="--")
        ax.axhline(REL_DEGRADED, color="orange", lw=0.6, ls="--")
        ax.set_ylim(FLOOR / 3, 30)
        ax.set_title(_series_title(fr, series), fontsize=8)
        zero = " (0 at the far left)" if any(cr.case.x == 0 for cr in cases) else ""
        ax.set_xlabel(_XLABELS.get(fr.name, "parameter") + zero, fontsize=7)
        ax.set_ylabel("relative error vs 50 digits", fontsize=7)
        ax.tick_params(which="both", labelsize=7)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=6, loc="center right")
    fig.suptitle("Inverse dynamics against the 50-digit reference (dashed: degraded / unusable thresholds; "
                 f"errors of 0 drawn at {FLOOR:.0e}; crosses: NaN/Inf)", fontsize=9)
    return fig


def conditioning_figure(families: list[FamilyResult]):
    """cond(M) and the equilibrated cond against the swept parameter, per family; an infinite
    condition number is drawn as a triangle at the top."""
    fig, panels = _family_panels(families)
    for ax, fr, cases, series, xmap in panels:
        finite = [v for cr in cases for v in (cr.cond_raw, cr.cond_eq) if math.isfinite(v)]
        top = 10.0 ** math.ceil(math.log10(max(finite + [COND_SINGULAR]))) * 100
        for si, s in enumerate(series):
            crs = sorted([cr for cr in cases if cr.case.series == s], key=lambda cr: xmap[id(cr)])
            xs = np.array([xmap[id(cr)] for cr in crs])
            ls = _SERIES_STYLES[si % 4]
            for attr, color, lab in (("cond_raw", "#1f77b4", "cond(M)"), ("cond_eq", "#2ca02c", "cond_eq")):
                v = np.array([getattr(cr, attr) for cr in crs])
                ax.loglog(xs, np.where(np.isfinite(v), v, np.nan), color=color, ls=ls, marker=".", lw=1,
                          label=lab if si == 0 else None)
                inf = ~np.isfinite(v)
                if inf.any():
                    ax.scatter(xs[inf], np.full(inf.sum(), top), marker="^", color=color, s=30, zorder=5,
                               label=f"{lab} = inf" if si == 0 else None)
            sing = [i for i, cr in enumerate(crs) if cr.singular_samples]
            if sing:
                ys = [crs[i].cond_raw if math.isfinite(crs[i].cond_raw) else top for i in sing]
                ax.scatter(xs[sing], ys, marker="o", facecolors="none", edgecolors="red", s=60, zorder=6,
                           label="singular (exact cause)" if si == 0 else None)
        ax.axhline(COND_ILL, color="orange", lw=0.6, ls="--")
        ax.axhline(COND_SINGULAR, color="red", lw=0.6, ls="--")
        ax.set_ylim(1, top * 10)
        ax.set_title(_series_title(fr, series), fontsize=8)
        zero = " (0 at the far left)" if any(cr.case.x == 0 for cr in cases) else ""
        ax.set_xlabel(_XLABELS.get(fr.name, "parameter") + zero, fontsize=7)
        ax.tick_params(which="both", labelsize=7)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=6)
    fig.suptitle("Condition number of the mass matrix from CRBA (dashed: ill-conditioned / numerically singular)",
                 fontsize=9)
    return fig


# ----------------------------------------------------------------------------- run
def method_options(profile: Profile) -> dict[str, dict]:
    """The :func:`prepare` options of the profile: the symbolic budget of ``lagrange``."""
    return {"lagrange": {"budget": profile.lagrange_budget}}


def evaluate_families(profile: Profile, methods: list[str], log=print) -> list[FamilyResult]:
    memo: dict = {}
    out = []
    for name, make in FAMILIES.items():
        log(f"stability: family {name}")
        doc = " ".join((make.__doc__ or "").split())
        out.append(evaluate_family(name, make(profile), methods, memo, doc, method_options(profile)))
    return out


def findings_markdown(families: list[FamilyResult], methods: list[str], forward=None) -> str:
    """Bold lines: where each method is unusable (inverse dynamics, and forward dynamics from its M
    and h), then where the mass matrix is singular or ill-conditioned."""
    L = []
    for m in methods:
        fams = [fr for fr in families if m in fr.warnings]
        fails = [rt for rt in (forward.method_trips if forward else []) if rt.method == m and rt.verdict == "FAIL"]
        if not fams and not fails:
            continue
        base = next((fr for fr in fams if fr.name == BASELINE), None)
        if base is not None:
            L.append(f"- **`{m}` is unusable already on the {BASELINE}: it is wrong, not unstable.** "
                     f"{base.warnings[m]}")
            L += [f"  - {fr.warnings[m]}" for fr in fams if fr is not base]
        elif fams:
            L.append(f"- **`{m}` breaks on {', '.join(fr.name for fr in fams)}.**")
            L += [f"  - {fr.warnings[m]}" for fr in fams]
        for rt in fails:
            L.append(f"  - **forward dynamics from `{m}`'s M and h does not reproduce the motion ({rt.case}): "
                     f"deviation {rt.error:.1e} > tolerance {rt.tolerance:.1e}**")
    ok = [m for m in methods if not any(m in fr.warnings for fr in families)]
    if ok:
        L.append(f"- {', '.join(f'`{m}`' for m in ok)}: usable on every family where they ran "
                 f"(relative error at most {max((cr.rows[m].rel_err for fr in families for cr in fr.results for m in ok if m in cr.rows and math.isfinite(cr.rows[m].rel_err)), default=math.nan):.1e}, "
                 "no NaN/Inf); see the summary for skips.")
    L += [f"- **{fr.mass_warning}**" for fr in families if fr.mass_warning]
    return "\n".join(L)


def report_markdown(profile: Profile, methods: list[str], families: list[FamilyResult], forward,
                    seconds: float, figures: list[str]) -> str:
    from exo_bench.bench.forward import forward_markdown
    from exo_bench.bench.reporting import provenance

    refs = sorted({cr.reference for fr in families for cr in fr.results})
    L = ["# Numerical stability: where each method breaks", "",
         provenance("exo-bench stability" + (" --full" if profile.full_cases else "")), "",
         f"- **profile**: {profile.name} ({profile.samples} states per case"
         f"{'; `exo-bench stability --full` runs the whole sweep' if not profile.full_cases else ''}); "
         f"total {seconds:.0f} s on this machine",
         f"- **methods** (the registry at run time): {', '.join(methods)}",
         f"- **reference**: {'; '.join(refs)}",
         f"- **lagrange symbolic budget**: {profile.lagrange_budget:g} s "
         "per mechanism (over it, the method is recorded as skipped with the reason)",
         "- **quantities**: generalised forces of the paper's absolute coordinates (M_phi, M_psi in N m, F in N)", ""]
    L += ["## Findings", "", findings_markdown(families, methods, forward), ""]
    L += [thresholds_markdown(families, min(profile.wp_rtols)), family_summary_markdown(families, methods),
          "## Families in detail", ""]
    L += [family_detail_markdown(fr, methods) for fr in families]
    L += [f"![relative errors per family]({figures[0]})", "", f"![condition numbers per family]({figures[1]})", ""]
    L += [forward_markdown(forward)]
    L += [f"![work-precision]({figures[2]})", "", f"![stiff rods]({figures[3]})", ""]
    return "\n".join(L)


def run(args) -> int:
    """``exo-bench stability [--full] [--reports DIR]``: write ``stability.md`` and its PNGs."""
    from exo_bench.bench.forward import forward_figures, run_forward
    from exo_bench.bench.methods import method_names
    from exo_bench.bench.reporting import REPORTS, atomic_write, save_figure

    profile = FULL if getattr(args, "full", False) else QUICK
    out = Path(args.reports) if getattr(args, "reports", None) else REPORTS
    methods = method_names()
    t0 = time.perf_counter()
    log = lambda msg: print(msg, flush=True)  # noqa: E731
    with warnings.catch_warnings():
        warnings.simplefilter("always", StabilityWarning)
        families = evaluate_families(profile, methods, log)
        forward = run_forward(profile, methods, log, PreparedSet(method_options(profile)))
    figs = {"stability-families.png": families_figure(families, methods),
            "stability-conditioning.png": conditioning_figure(families)}
    figs.update(forward_figures(forward))
    written = [save_figure(fig, out / name) for name, fig in figs.items()]
    text = report_markdown(profile, methods, families, forward, time.perf_counter() - t0, list(figs))
    written.append(atomic_write(out / "stability.md", text))
    for p in written:
        print(f"wrote {p}")
    # Exit status: the suite's own physics (Pinocchio's round trips, energy bounds). A registered
    # method whose M and h fail the round trip is a finding of the report, not a failure of the run.
    bad_rt = [rt for rt in forward.round_trips if rt.verdict == "FAIL"]
    bad_en = [r for r in forward.energy if r.sim.ok and not r.passed]
    for rt in bad_rt:
        print(f"round trip FAILED: {rt.case}, {rt.method}, {rt.integrator} rtol {rt.rtol:g}: deviation "
              f"{rt.error:.2e} > tolerance {rt.tolerance:.2e}")
    for r in bad_en:
        print(f"energy drift above its bound: {r.case}, {r.integrator} rtol {r.rtol:g}: {r.drift:.2e} > {r.bound:.2e}")
    return 1 if bad_rt or bad_en else 0
