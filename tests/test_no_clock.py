"""No test depends on the machine's speed (issue 34, F1 and F2): hypothesis's clocks are off for every
collected hypothesis test (tests/conftest.py), so a loaded machine cannot fail one by its deadline or
its ``too_slow`` health check."""

from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st


@settings(deadline=200, suppress_health_check=[HealthCheck.filter_too_much], max_examples=3)
@given(st.integers())
def test_a_test_that_asks_for_a_deadline(x):
    """A hypothesis test whose own settings ask for a 200 ms deadline and leave too_slow on (checked below)."""
    assert isinstance(x, int)


@pytest.mark.case("F1")
def test_no_hypothesis_test_has_a_deadline_or_a_speed_health_check(request):
    """Every collected hypothesis test runs without a deadline and with the too_slow health check off,
    whatever its own settings asked for (a test here asks for a 200 ms deadline)."""
    hyp = [it for it in request.session.items if getattr(getattr(it, "obj", None), "is_hypothesis_test", False)]
    assert any(it.name == "test_a_test_that_asks_for_a_deadline" for it in hyp)
    bad = [
        it.nodeid
        for it in hyp
        if it.obj._hypothesis_internal_use_settings.deadline is not None
        or HealthCheck.too_slow not in it.obj._hypothesis_internal_use_settings.suppress_health_check
    ]
    assert not bad, f"hypothesis tests timed on the wall clock: {bad}"
    # nor by the run: every run draws the same examples (a seed from the test's name, no example
    # database replaying what another run found), so a run of the suite is repeatable
    drawn = [it.nodeid for it in hyp if not it.obj._hypothesis_internal_use_settings.derandomize]
    stored = [it.nodeid for it in hyp if it.obj._hypothesis_internal_use_settings.database is not None]
    assert not drawn and not stored, f"hypothesis tests drawing other examples in each run: {drawn + stored}"
