"""Which rows of bench/test_compose.py run is predicted from their size, not timed (issue 34, the guide:
"Budgets and memory are predicted before the work"; "no budgets near the scheduler's jitter").

Before this, each row composed within the profile's 20 s budget on the wall clock and turned into a
skip when it ran out: sympy-lagrangesmethod at 3D n=2 took 5.3 s on a quiet machine and 14.6 s under
load, so under more load the quick profile's row became a skip, silently.
"""

from __future__ import annotations

import time

import pytest

from exo_bench.bench.perf import profiles
from exo_bench.bench.perf.profiles import SWEEPS


def _rows(sweep):
    """Every (method, n, dim) that bench/test_compose.py's profile runs (its _cases, topology aside)."""
    rows = {(m, n, d) for d, ns in ((2, sweep.compose_2d), (3, sweep.compose_3d)) for n in ns for m, _ in _methods(d)}
    rows |= {(m, 5, 3) for m in ("lagrange", "matrix", "recurrence")}
    rows |= {(m, n, 3) for n in sweep.compose_3d_fast for m in ("matrix", "recurrence")}
    return sorted(rows)


def _methods(dim):
    return [(m, d) for m, d in profiles.COMPOSE_POINTS if d == dim]


@pytest.fixture
def no_clock(monkeypatch):
    """Every clock of ``time`` raises: a decision that reads one fails."""

    def clock(*_a):
        raise AssertionError("the decision read a clock")

    for name in ("time", "monotonic", "perf_counter", "process_time", "time_ns", "monotonic_ns", "perf_counter_ns"):
        monkeypatch.setattr(time, name, clock)


@pytest.mark.parametrize("profile", sorted(SWEEPS))
def test_the_decision_reads_no_clock_and_every_profile_row_fits(no_clock, profile):
    """Every row of the quick and full profiles is predicted within its budget (they all ran in the
    reference run), decided with every clock of ``time`` raising."""
    sweep = SWEEPS[profile]
    skipped = {r: profiles.predicted_skip(*r, sweep.compose_budget) for r in _rows(sweep)}
    assert not {r: why for r, why in skipped.items() if why}
    assert len(skipped) >= 20


def test_a_row_over_the_budget_is_skipped_naming_the_prediction(no_clock):
    """sympy-lagrangesmethod grows like n^3.7 in 3D: at n=8 it is predicted near 870 s, over the full
    profile's 300 s; the reason names the prediction, the model's size and the budget."""
    why = profiles.predicted_skip("sympy-lagrangesmethod", 8, 3, 300.0)
    assert why is not None
    predicted = profiles.predicted_seconds("sympy-lagrangesmethod", 8, 3)
    assert 600 < predicted < 1200
    assert f"{predicted:.3g} s" in why and "n=8" in why and "dim=3" in why and "300 s" in why
    assert profiles.predicted_skip("sympy-lagrangesmethod", 5, 3, 300.0) is None


@pytest.mark.parametrize("key", sorted(profiles.COMPOSE_POINTS))
def test_the_prediction_grows_with_n_and_meets_its_points(key):
    """Monotone in n (a larger model never runs where a smaller one skipped) and equal to each measured point."""
    method, dim = key
    series = [profiles.predicted_seconds(method, n, dim) for n in range(1, 120)]
    assert all(b >= a for a, b in zip(series, series[1:]))
    for n, s in profiles.COMPOSE_POINTS[key]:
        assert profiles.predicted_seconds(method, n, dim) == pytest.approx(s, rel=1e-12)


def test_an_unknown_method_is_named():
    with pytest.raises(ValueError, match=r"field 'method'.*'pydy'"):
        profiles.predicted_seconds("pydy", 2, 3)


def test_the_benchmark_decides_by_the_prediction():
    """bench/test_compose.py skips by :func:`predicted_skip` and gives a running row LOAD_ALLOWANCE x the
    budget; no over-budget exception of a composition turns into a skip (it fails the row)."""
    from pathlib import Path

    src = (Path(__file__).parents[1] / "bench" / "test_compose.py").read_text()
    assert "predicted_skip(method, n, dim, sweep.compose_budget)" in src
    assert "_composer(method, LOAD_ALLOWANCE * sweep.compose_budget)" in src
    assert 'pytest.skip(f"{method}: {reason}")' in src and src.count("pytest.skip(") == 1
