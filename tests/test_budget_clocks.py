"""Budgets other than lagrange's (tests/test_lagrange_budget.py) read an injectable clock, so that a test
makes them fire, or not, at a known point whatever the machine's speed (issue 34, F1)."""

from __future__ import annotations

import itertools

import pytest

from exo_bench.bench.output.equation_pages import EquationsBudget, _Clock
from exo_bench.models.mechanism.presets import fig1


def ticks(step: float):
    """A clock that advances ``step`` seconds at every reading (0, step, 2 step, ...)."""
    return itertools.count(0.0, step).__next__


@pytest.mark.case("F1")
def test_the_equations_budget_fires_between_phases_by_its_clock():
    """The equations budget (exo-bench equations --budget) is checked between phases on its clock: with
    one of 1 s per reading, a 2.5 s budget passes two checks and stops at the third, naming the phase."""
    clock = _Clock(fig1(2), "c", 2.5, clock=ticks(1.0))
    clock.check("composing")
    clock.check("simplifying")
    with pytest.raises(EquationsBudget, match=r"took 3\.0 s by the end of writing, over the budget of 2\.5 s"):
        clock.check("writing")


@pytest.mark.case("F1")
def test_a_stopped_clock_never_exceeds_the_equations_budget():
    """On a clock that stands still the equations budget never fires, however many phases (no wall clock)."""
    clock = _Clock(fig1(2), "c", 10.0, clock=lambda: 0.0)
    for phase in range(100):
        clock.check(f"phase {phase}")
