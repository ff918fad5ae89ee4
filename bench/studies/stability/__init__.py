"""``exo-bench stability``: where each method breaks, and the forward-dynamics round trip.

A benign baseline and six families of extreme cases (:data:`~exo_bench.bench.studies.stability.cases.FAMILIES`), each a list of
:class:`~exo_bench.bench.studies.stability.cases.Case` (a mechanism and states). For every case and every method registered in :data:`exo_bench.api.methods.METHODS` *at run
time*, the report gives the largest absolute and relative error against the 50-digit reference,
the number of NaN/Inf values, and the condition number of the mass matrix; a method that is
missing, over its time budget or raising is recorded as such (one line), never a crash.

Verdicts and their thresholds (justified in the report, see :func:`~exo_bench.bench.studies.stability.report.thresholds_markdown`):

* inverse dynamics of a method on a case is **unusable** when it returns any NaN/Inf or its
  relative error exceeds :data:`~exo_bench.bench.studies.stability.cases.REL_UNUSABLE`, **degraded** above :data:`~exo_bench.bench.studies.stability.cases.REL_DEGRADED`; an
  unusable method raises :class:`~exo_bench.bench.studies.study.UnusableMethodWarning` and a bold line in the report;
* the mass matrix (forward dynamics) is **singular** where :func:`models.forward_dynamics.
  singular_reasons` finds an exact cause (vertical rod, zero length, massless link),
  **numerically singular** when ``cond(M) >= COND_SINGULAR`` and **ill-conditioned** when
  ``cond(M) >= COND_ILL`` (:class:`~exo_bench.bench.studies.stability.cases.IllConditionedWarning`).

The forward-dynamics part (round trip, energy drift, stiff rods, work-precision diagrams) lives
in the ``forward_*`` modules; :func:`exo_bench.bench.studies.stability.report.run` writes both into
``reports/stability.md`` with its PNGs.

What belongs here, one module per part of the two studies: ``cases`` and ``forward_cases`` (what is
computed), ``evaluation`` and ``forward_evaluation`` (computing it: the forward study's energy drift,
stiff rods and terms per method; its round trips in ``forward_round_trip``), ``figures`` (every
figure of the report), ``report`` (the Markdown of the families and the chart-free section, and
``run``, the ``exo-bench stability`` job) and ``forward_report`` (the forward-dynamics sections, the
analytic Jacobian's among them). Import each name from the module that defines it.
"""
