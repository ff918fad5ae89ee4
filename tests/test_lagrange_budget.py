"""Time budgets: behaviour, not seconds. Over budget the work raises BudgetExceeded with a reason
naming the work, n, dim and the budget; the reason is recorded as a skip; nothing half-done is
cached; an unfinished derivation is not started again with no more time; the alarm is handed back.

No test asserts elapsed time or races the wall clock (issue 34, F1: a 50 ms budget raced the
derivation and failed 3 of 37 times). Budgets read an injected clock (:func:`ticks`: every reading
advances a fixed step, so a budget of B seconds fires at a known cooperative check, on any machine
under any load), or, where the real SIGALRM path is tested, the work is unbounded, so the alarm is
the only way out and a broken alarm is a failure, not a hang.
"""

import itertools
import signal
import threading

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.bench.studies.study import run_methods
from exo_bench.lagrange import BudgetExceeded, derive
from exo_bench.lagrange import derivation as dv
from exo_bench.lagrange import numeric as ln
from exo_bench.lagrange.budget import budget_clock, time_budget
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.mechanism.presets import chain


def ticks(step: float = 1.0):
    """A clock that advances ``step`` seconds at every reading (0, step, 2 step, ...)."""
    return itertools.count(0.0, step).__next__


def _cached(mech):
    """What the derivation and compilation caches hold for ``mech`` (and its structure)."""
    st = dv.structure_of(mech)
    return (
        {k for k in dv._SYMBOLIC if k[0] == st}
        | {k for k in dv._NUMERIC if k[0] == mech}
        | {k for k in ln._CACHE if k[0] == mech}
    )


@pytest.mark.case("F1")
def test_a_budget_that_runs_out_raises_naming_the_work_n_dim_and_budget_and_caches_nothing():
    """A budget that runs out on the injected clock stops the derivation at its first cooperative check,
    names the work, n, dim and the budget, and caches nothing. The clock advances 1 s per reading,
    so the 0.05 s budget is over at the first check on any machine (no race with the wall clock)."""
    m = chain(12, 3)
    with budget_clock(ticks(1.0)), pytest.raises(BudgetExceeded) as info:
        derive(m, budget=0.05)
    reason = info.value.skip_reason
    assert "Lagrange II derivation" in reason and "n=12" in reason and "dim=3" in reason and "0.05 s" in reason
    assert (info.value.nlinks, info.value.dim, info.value.budget) == (12, 3, 0.05)
    assert not _cached(m)  # no half-done derivation is kept
    assert dv._FAILED[(dv.structure_of(m), "poly")] > 0  # the attempt is remembered
    with pytest.raises(ValueError, match="its derivation alone over the budget of 50 ms"):
        prepare(m, "lagrange", budget=0.05)  # refused up front by the estimate (issue 26)
    from exo_bench.lagrange.prepared import LagrangeModel

    with budget_clock(ticks(0.01)), pytest.raises(BudgetExceeded):
        LagrangeModel(m, budget=0.05)  # the class itself: the budget stops the work
    assert not _cached(m)
    assert ln._FAILED[(m, "equations")] > 0


@pytest.mark.case("F1")
def test_a_budget_that_does_not_run_out_lets_the_derivation_finish():
    """A derivation whose budget does not run out on the injected clock finishes and is cached, whatever
    the wall clock says: a stopped clock never exceeds even a budget of 1 ns."""
    m = chain(2, 2)
    dv.clear_cache()
    with budget_clock(lambda: 0.0):
        d = derive(m, budget=1e-9)
    assert len(d.equations) == 4 and _cached(m)


@pytest.mark.case("F1")
def test_an_unfinished_derivation_is_not_started_again_with_no_more_time(monkeypatch):
    """An unfinished derivation is refused at once when a later call has no more time than the first
    attempt ran (on the injected clock), and is started again when it has more."""
    m = chain(11, 3)
    dv.clear_cache()
    with budget_clock(ticks(1.0)), pytest.raises(BudgetExceeded):
        derive(m, budget=3.0)  # stops at the fourth reading of the clock: ran at least 3 s
    ran = dv._FAILED[(dv.structure_of(m), "poly")]
    assert ran >= 3.0
    started = []

    def record(*a, **k):
        started.append(a)
        raise RuntimeError("started")

    monkeypatch.setattr(dv, "_derive_symbolic", record)
    with (
        budget_clock(ticks(1.0)),
        pytest.raises(BudgetExceeded, match="earlier attempt ran .* without finishing") as info,
    ):
        derive(m, budget=ran)
    assert not started and "n=11" in info.value.skip_reason
    assert not _cached(m)
    with budget_clock(ticks(1.0)), pytest.raises(RuntimeError, match="started"):
        derive(m, budget=ran + 10.0)  # more time than the first attempt had: tried again
    assert len(started) == 1


def test_run_methods_records_an_over_budget_method_as_skipped_with_its_reason():
    m = chain(10, 3)
    mo = smooth_random_motion(m, np.linspace(0, 1, 5), seed=1)
    study = run_methods("budget", m, mo, "random", ["pinocchio", "lagrange"], options={"lagrange": {"budget": 0.1}})
    r = study.results["lagrange"]
    assert r.tau is None and r.error is None
    # refused before it starts (the cost model predicts the derivation alone exceeds the budget)
    assert "budget of 100 ms" in r.skipped and "n=10" in r.skipped and "dim=3" in r.skipped
    assert study.results["pinocchio"].ok
    assert not _cached(m)


def test_a_bad_budget_is_a_value_error():
    with pytest.raises(ValueError, match="budget"):
        derive(chain(2, 2), budget=0)
    for bad in (0, -1.0, "soon", True, float("inf"), float("nan")):
        with pytest.raises(
            ValueError, match="lagrange: option 'budget': expected a positive, finite number of seconds"
        ):
            prepare(chain(9, 2), "lagrange", budget=bad)


@pytest.mark.case("F1")
def test_outside_the_main_thread_the_budget_is_checked_cooperatively():
    """Outside the main thread the derivation's own checks stop it at its first cooperative check (on
    the thread's injected clock), and the thread's SIGALRM disposition is left alone. No signal can
    be armed in another thread; the main thread's clock is not changed by the thread's."""
    caught, handlers = [], []
    m = chain(10, 2)
    before = signal.getsignal(signal.SIGALRM)

    def work():
        try:
            with budget_clock(ticks(1.0)):
                derive(m, budget=0.1)
        except BudgetExceeded as e:
            caught.append(e)
        handlers.append(signal.getsignal(signal.SIGALRM))

    t = threading.Thread(target=work)
    t.start()
    t.join(timeout=600)  # a safety net: the thread stops at its first check
    assert not t.is_alive()
    assert caught and "n=10" in caught[0].skip_reason and "dim=2" in caught[0].skip_reason
    assert handlers == [before] and signal.getitimer(signal.ITIMER_REAL)[0] == 0
    assert not _cached(m)
    with time_budget(600.0, "main", 1, 1) as dl:  # the main thread still reads the real clock
        assert dl.clock is __import__("time").perf_counter


@pytest.mark.case("F1")
def test_an_injected_clock_arms_no_alarm_and_decides_alone():
    """Under an injected clock no SIGALRM is armed and the budget fires exactly when that clock passes
    its end: here at the fourth cooperative check of a 3 s budget on a clock of 1 s per reading."""
    before = signal.getsignal(signal.SIGALRM)
    checks = []
    with pytest.raises(BudgetExceeded, match="counted work") as info:
        with time_budget(3.0, "counted work", 2, 2, clock=ticks(1.0)) as dl:
            assert signal.getitimer(signal.ITIMER_REAL)[0] == 0 and signal.getsignal(signal.SIGALRM) is before
            for k in range(100):
                checks.append(k)
                dl.check()
    assert checks == [0, 1, 2, 3] and info.value.elapsed == 5.0  # the fourth check raised; one more reading


def test_the_alarm_is_handed_back_after_a_budget():
    before = signal.getsignal(signal.SIGALRM)
    with time_budget(600.0, "work", 1, 2):  # never reached: the body is instant
        assert signal.getitimer(signal.ITIMER_REAL)[0] > 0
        assert signal.getsignal(signal.SIGALRM) is not before
    assert signal.getsignal(signal.SIGALRM) is before
    assert signal.getitimer(signal.ITIMER_REAL)[0] == 0


@pytest.mark.case("F1")
def test_a_nested_budget_is_bounded_by_the_enclosing_one():
    """The enclosing budget's SIGALRM interrupts an endless loop and is the one named, never the inner
    one. The inner budget (30 s) is never reached: the enclosing one (0.1 s) interrupts the loop
    whatever the machine's speed, as the loop only ends through the alarm (a guard of one billion
    iterations turns a broken alarm into a failure instead of a hang)."""
    with pytest.raises(BudgetExceeded, match="outer work") as info:
        with time_budget(0.1, "outer work", 7, 3):
            with time_budget(30.0, "inner work", 7, 3):
                for _ in range(10**9):
                    sum(range(1000))
                pytest.fail("the enclosing budget never interrupted the work")
    assert info.value.budget == 0.1 and (info.value.nlinks, info.value.dim) == (7, 3)
    assert signal.getitimer(signal.ITIMER_REAL)[0] == 0
