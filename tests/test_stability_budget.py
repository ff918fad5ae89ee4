"""The stability study decides which lagrange rows skip from the cost model's prediction, not from
the wall clock: "budgets and memory are predicted before the work" (issue 34's leftovers).

A derivation predicted over the profile's ``lagrange_budget`` is skipped without starting, naming the
prediction; one predicted within it runs with :data:`LOAD_ALLOWANCE` times the budget, so that a
loaded machine (the derivation taking several times its quiet time) still finishes it rather than
turning the row into a skip. The same rows run or skip on any machine.
"""

from __future__ import annotations


import numpy as np
import pytest

from exo_bench.api import PreparedSet
from exo_bench.api.cost_model import estimate
from exo_bench.bench.studies.stability import cases, evaluation
from exo_bench.models.mechanism.presets import chain


def _case(mech):
    rng = np.random.default_rng(0)
    q = rng.uniform(0.2, 0.6, (2, mech.dof))
    return cases.Case("f", "s", "c", 0.0, mech, q, np.zeros_like(q), np.zeros_like(q))


def test_a_derivation_predicted_over_the_budget_is_skipped_without_starting(monkeypatch):
    """The row is skipped naming the predicted seconds and the budget; no derivation starts."""
    mech = chain(6, 3)
    predicted = estimate(mech, "lagrange").setup_seconds
    budget = predicted / 2
    models = PreparedSet(
        evaluation.method_options(cases.QUICK.__class__(**{**vars(cases.QUICK), "lagrange_budget": budget}))
    )

    def derive(*a, **k):
        raise AssertionError("a derivation started")

    monkeypatch.setattr("exo_bench.lagrange.derive", derive)
    row = evaluation.evaluate_case(_case(mech), ["lagrange"], {}, models).rows["lagrange"]
    assert row.status == "skipped" and "predicted" in row.reason and f"{budget:g} s" in row.reason, row.reason


def test_a_derivation_predicted_within_the_budget_runs_with_the_load_allowance():
    """The prepared model's derivation budget is LOAD_ALLOWANCE times the profile's (it was the
    profile's: a loaded machine turned rows into skips)."""
    opts = evaluation.method_options(cases.QUICK)
    assert opts["lagrange"]["budget"] == evaluation.LOAD_ALLOWANCE * cases.QUICK.lagrange_budget
    assert evaluation.LOAD_ALLOWANCE >= 10


@pytest.mark.parametrize("profile", [cases.QUICK, cases.FULL], ids=lambda p: p.name)
def test_the_skipped_rows_are_those_the_cost_model_predicts(profile):
    """Which mechanisms of the profile's families skip lagrange is a function of the prediction
    alone (listed here, the same on every machine)."""
    skipped = evaluation.predicted_skips(profile)
    for name, reason in skipped.items():
        assert "predicted" in reason, (name, reason)
    assert skipped == evaluation.predicted_skips(profile)
