"""Errata of the paper's formulas, found by computation: ``exo-bench errata`` -> ``reports/errata.md``.

Every formula of :mod:`matrix_method.printed` (encoded once, exactly as printed) is evaluated on
seeded random states of the models it speaks about and compared with two independent witnesses:

* **Lagrange**: :func:`lagrange.derive` (sympy, from the point masses' T and Pi), its matrices
  and equations lambdified;
* **Pinocchio**: the mass matrix (CRBA) and bias forces (RNEA) of the generated URDF, from which
  every matrix of eq. (5)/(17) is read off column by column (:func:`pinocchio_matrices`).

A formula *holds* when its largest error, relative to the largest magnitude of what it is compared
with, is at most :data:`TOLERANCE` for both witnesses on every model; otherwise it *fails*, and the
report gives the corrected form (a hypothesis encoded in :mod:`matrix_method.printed`) with its own
error. Nothing in the report is typed by hand: verdicts, errors and evidence come from this module.

Modules: ``witnesses`` (Lagrange and Pinocchio), ``checks`` (the verdicts), ``report`` (the
Markdown and :func:`run`). This package re-exports their public names.
"""

from exo_bench.bench.errata.witnesses import TOLERANCE, SAMPLES, SEED, TREES, CHAIN_LENGTHS, pinocchio_matrices, form_residual, PinocchioWitness, LagrangeWitness  # noqa: F401
from exo_bench.bench.errata.checks import Check, Verdict, prefix, prefix_states, spatial_models, check_transition, check_equation, chains, check_matrix, check_branch_rule, check_all, singular_configuration, Singular, check_singular, gait_effect  # noqa: F401
from exo_bench.bench.errata.report import Results, compute, render, write_report, run  # noqa: F401
