"""Errata of the paper's formulas, found by computation: ``exo-bench errata`` -> ``reports/errata.md``.

Every formula of :mod:`exo_bench.matrix_method.printed` (encoded once, exactly as printed) is evaluated on
seeded random states of the models it speaks about and compared with two independent witnesses:

* **Lagrange**: :func:`exo_bench.lagrange.derive` (sympy, from the point masses' T and Pi), its matrices
  and equations lambdified;
* **Pinocchio**: the mass matrix (CRBA) and bias forces (RNEA) of the generated URDF, from which
  every matrix of eq. (5)/(17) is read off column by column (:func:`pinocchio_matrices`).

A formula *holds* when its largest error, relative to the largest magnitude of what it is compared
with, is at most :data:`TOLERANCE` for both witnesses on every model; otherwise it *fails*, and the
report gives the corrected form (a hypothesis encoded in :mod:`exo_bench.matrix_method.printed`) with its own
error. Nothing in the report is typed by hand: verdicts, errors and evidence come from this package.

One responsibility per module: ``cases`` (the models and states each formula is checked on),
``witnesses`` (Lagrange and Pinocchio, the matrices read off them), ``evaluation`` (the checks,
the verdicts, the singular points and the gait), ``report`` (the Markdown, and :func:`run`, the
``exo-bench errata`` job). This package re-exports their public names.
"""

from exo_bench.bench.studies.errata.cases import (
    CHAIN_LENGTHS,
    SAMPLES,
    SEED,
    TREES,
    chains,
    prefix,
    prefix_states,
    singular_configuration,
    spatial_models,
)
from exo_bench.bench.studies.errata.witnesses import (
    LagrangeWitness,
    PinocchioWitness,
    form_residual,
    pinocchio_matrices,
)
from exo_bench.bench.studies.errata.evaluation import (
    TOLERANCE,
    Check,
    Results,
    Singular,
    Verdict,
    check_all,
    check_branch_rule,
    check_equation,
    check_matrix,
    check_singular,
    check_transition,
    compute,
    gait_effect,
)
from exo_bench.bench.studies.errata.report import render, run, write_report

__all__ = [
    "CHAIN_LENGTHS",
    "SAMPLES",
    "SEED",
    "TREES",
    "chains",
    "prefix",
    "prefix_states",
    "singular_configuration",
    "spatial_models",
    "LagrangeWitness",
    "PinocchioWitness",
    "form_residual",
    "pinocchio_matrices",
    "TOLERANCE",
    "Check",
    "Results",
    "Singular",
    "Verdict",
    "check_all",
    "check_branch_rule",
    "check_equation",
    "check_matrix",
    "check_singular",
    "check_transition",
    "compute",
    "gait_effect",
    "render",
    "run",
    "write_report",
]
