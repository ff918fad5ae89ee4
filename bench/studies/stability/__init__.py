"""``exo-bench stability``: where each method breaks, and the forward-dynamics round trip.

A benign baseline and six families of extreme cases (:data:`FAMILIES`), each a list of
:class:`Case` (a mechanism and states). For every case and every method registered in :data:`exo_bench.api.methods.METHODS` *at run
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
in the ``forward_*`` modules; :func:`run` writes both into ``reports/stability.md`` with its PNGs.

One responsibility per module: ``cases`` and ``forward_cases`` (what is computed),
``evaluation`` and ``forward_evaluation`` (computing it; the forward parts in ``forward_round_trip``,
``forward_energy`` and ``forward_terms``), ``figures`` and ``forward_figures``,
``report`` and ``forward_report`` (the Markdown, and :func:`run`, the ``exo-bench stability`` job).
This package re-exports their public names.
"""

from exo_bench.bench.studies.stability.forward_cases import (
    ATOL_FACTOR,  # noqa: F401
    TIGHTER,  # noqa: F401
    ROUND_TRIP_RULE,  # noqa: F401
    RoundTripCase,  # noqa: F401
    round_trip_cases,  # noqa: F401
    SpringCase,  # noqa: F401
    conservative_cases,  # noqa: F401
    hanging_chain,  # noqa: F401
    stiff_case,  # noqa: F401
)
from exo_bench.bench.studies.stability.cases import (
    EPS,  # noqa: F401
    REL_UNUSABLE,  # noqa: F401
    REL_DEGRADED,  # noqa: F401
    COND_ILL,  # noqa: F401
    COND_SINGULAR,  # noqa: F401
    IllConditionedWarning,  # noqa: F401
    Profile,  # noqa: F401
    QUICK,  # noqa: F401
    FULL,  # noqa: F401
    Case,  # noqa: F401
    BASELINE,  # noqa: F401
    family_baseline,  # noqa: F401
    family_near_vertical,  # noqa: F401
    family_removable,  # noqa: F401
    family_lengths,  # noqa: F401
    family_masses,  # noqa: F401
    family_large_n,  # noqa: F401
    family_fast_gaits,  # noqa: F401
    FAMILIES,  # noqa: F401
)
from exo_bench.bench.studies.stability.forward_round_trip import (
    Variational,  # noqa: F401
    variational,  # noqa: F401
    a_priori_bound,  # noqa: F401
    RoundTrip,  # noqa: F401
    round_trip_run,  # noqa: F401
    round_trip,  # noqa: F401
)
from exo_bench.bench.studies.stability.forward_energy import (
    energy_gradient,  # noqa: F401
    energy_bound,  # noqa: F401
    EnergyRun,  # noqa: F401
    energy_drift,  # noqa: F401
    StiffRun,  # noqa: F401
    stiff_run,  # noqa: F401
)
from exo_bench.bench.studies.stability.forward_terms import TermsRow, terms_agreement, SingularDemo, singular_demos  # noqa: F401
from exo_bench.bench.studies.stability.forward_evaluation import ForwardResults, rt_failed, run_forward  # noqa: F401
from exo_bench.bench.studies.stability.evaluation import (
    reference_forces,  # noqa: F401
    MethodRow,  # noqa: F401
    CaseResult,  # noqa: F401
    evaluate_case,  # noqa: F401
    equilibrated_mu_condition,  # noqa: F401
    FamilyResult,  # noqa: F401
    evaluate_family,  # noqa: F401
    method_options,  # noqa: F401
    evaluate_families,  # noqa: F401
)
from exo_bench.bench.studies.stability.forward_figures import work_precision_figure, stiff_figure, forward_figures  # noqa: F401
from exo_bench.bench.studies.stability.figures import FLOOR, families_figure, conditioning_figure  # noqa: F401
from exo_bench.bench.studies.stability.forward_report import forward_markdown  # noqa: F401
from exo_bench.bench.studies.stability.report import (
    baseline_level,  # noqa: F401
    thresholds_markdown,  # noqa: F401
    family_summary_markdown,  # noqa: F401
    family_detail_markdown,  # noqa: F401
    findings_markdown,  # noqa: F401
    report_markdown,  # noqa: F401
    run,  # noqa: F401
)
from exo_bench.bench.studies.study import StabilityWarning, UnusableMethodWarning  # noqa: F401
from exo_bench.bench.studies.stability.forward_evaluation import analytic_grid, analytic_stiff  # noqa: F401
from exo_bench.bench.studies.stability.forward_jacobian import SAME_ERROR, Pair, pairs, verdict, jacobian_markdown  # noqa: F401
