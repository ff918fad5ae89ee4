"""Time budgets: a large model with a tiny budget is skipped quickly, with a reason naming n and dim."""

import signal
import threading
import time

import numpy as np

from exo_bench import prepare
import pytest

from exo_bench.bench.study import run_methods
from exo_bench.lagrange import BudgetExceeded, derive
from exo_bench.lagrange.budget import time_budget
from exo_bench.models.motion import smooth_random_motion
from exo_bench.models.presets import chain


def test_tiny_budget_on_a_large_model_raises_quickly_naming_n_and_dim():
    t0 = time.perf_counter()
    with pytest.raises(BudgetExceeded) as info:
        derive(chain(12, 3), budget=0.05)
    assert time.perf_counter() - t0 < 1.0
    reason = info.value.skip_reason
    assert "n=12" in reason and "dim=3" in reason and "0.05 s" in reason
    assert isinstance(info.value, Exception)


def test_an_unfinished_derivation_is_not_retried_with_no_more_time():
    m = chain(11, 3)
    with pytest.raises(BudgetExceeded):
        derive(m, budget=0.3)
    t0 = time.perf_counter()
    with pytest.raises(BudgetExceeded, match="earlier attempt"):
        derive(m, budget=0.2)
    assert time.perf_counter() - t0 < 0.1


def test_run_methods_records_an_over_budget_method_as_skipped():
    m = chain(10, 3)
    mo = smooth_random_motion(m, np.linspace(0, 1, 5), seed=1)
    study = run_methods("budget", m, mo, "random", ["pinocchio", "lagrange"], options={"lagrange": {"budget": 0.1}})
    r = study.results["lagrange"]
    assert r.tau is None and r.error is None
    assert "n=10" in r.skipped and "dim=3" in r.skipped
    assert study.results["pinocchio"].ok


def test_a_bad_budget_is_a_value_error():
    with pytest.raises(ValueError, match="budget"):
        derive(chain(2, 2), budget=0)
    for bad in (0, -1.0, "soon", True):
        with pytest.raises(ValueError, match="lagrange: option 'budget': expected a positive number of seconds"):
            prepare(chain(9, 2), "lagrange", budget=bad)


def test_outside_the_main_thread_the_budget_is_checked_cooperatively():
    caught = []

    def work():
        try:
            derive(chain(10, 2), budget=0.1)
        except BudgetExceeded as e:
            caught.append(e)

    t = threading.Thread(target=work)
    t0 = time.perf_counter()
    t.start()
    t.join()
    assert caught and "n=10" in caught[0].skip_reason and time.perf_counter() - t0 < 2.0


def test_the_alarm_is_handed_back_after_a_budget():
    before = signal.getsignal(signal.SIGALRM)
    with time_budget(5.0, "work", 1, 2):
        assert signal.getitimer(signal.ITIMER_REAL)[0] > 0
    assert signal.getsignal(signal.SIGALRM) is before
    assert signal.getitimer(signal.ITIMER_REAL)[0] == 0


def test_a_nested_budget_is_bounded_by_the_enclosing_one():
    t0 = time.perf_counter()
    with pytest.raises(BudgetExceeded, match="outer work"):
        with time_budget(0.1, "outer work", 7, 3):
            with time_budget(30.0, "inner work", 7, 3):
                while True:
                    sum(range(1000))
    assert time.perf_counter() - t0 < 1.0
    assert signal.getitimer(signal.ITIMER_REAL)[0] == 0
