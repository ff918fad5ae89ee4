"""Issue 35's section of reports/scaling.md (bench/perf/reports/goals_call_overhead.py) from
synthetic timings: every goal is listed, each verdict follows its ratio and bound, an unmeasured
goal is never met, and the scaling report carries the section. No timing is taken here."""

from __future__ import annotations

import pandas as pd
import pytest

from exo_bench.bench.perf.reports import goals_call_overhead as g

RNEA = 3.5e-6


def _figures(**ratios) -> dict:
    """A measure() result whose goal ratios are ``ratios`` (goal numerator key -> ratio)."""
    t = {"rnea": RNEA, "inverse_batch_unchecked": 5e-4, "forward_batch_unchecked": 2e-3}
    for goal in g.GOALS:
        t[goal.num] = ratios.get(goal.num, goal.bound / 2) * t[goal.den]
    return {"mechanism": "exo5-3d", "samples": 10_000, "rounds": 30, "calls_per_round": {"rnea": 2000}, "timings": t}


def _row(lines: list[str], goal: g.Goal) -> str:
    (row,) = [ln for ln in lines if ln.startswith(f"| {goal.what} |")]
    return row


def test_every_goal_is_listed_once_with_its_ratio_and_bound():
    lines = g.goals_lines(_figures())
    n = len(g.GOALS)
    assert n == 10 and len({goal.what for goal in g.GOALS}) == n  # issue 35's eight and issue 47's two derivatives
    for goal in g.GOALS:
        row = _row(lines, goal)
        assert f"| {goal.bound / 2:.3g}x | <= {goal.bound:g}x | **met** |" in row, row
    assert f"{n} of {n} goals met (judged on the medians)." in lines


@pytest.mark.parametrize("goal", g.GOALS, ids=lambda goal: goal.num)
def test_a_goal_over_its_bound_is_not_met_and_at_it_is_met(goal):
    over = g.goals_lines(_figures(**{goal.num: goal.bound * 1.01}))
    assert _row(over, goal).endswith("| **not met** |"), _row(over, goal)
    assert f"{len(g.GOALS) - 1} of {len(g.GOALS)} goals met (judged on the medians)." in over
    for other in g.GOALS:
        if other != goal:
            assert _row(over, other).endswith("| **met** |")
    at = g.verdicts(_figures(**{goal.num: goal.bound}))
    assert [ok for _, _, ok in at] == [True] * len(g.GOALS)


def test_the_default_call_33_us_against_rnea_3_5_us_is_about_9_4x():
    """The issue's figures before the work: 33 us against 3.5 us, not met."""
    r = _figures()
    r["timings"]["inverse_checked"] = 33e-6
    (verdict,) = [(ratio, ok) for goal, ratio, ok in g.verdicts(r) if goal.num == "inverse_checked"]
    assert verdict[0] == pytest.approx(33 / 3.5) and verdict[1] is False
    assert "| 33 us | bare `pin.rnea` | 9.43x | <= 0.3x | **not met** |" in _row(g.goals_lines(r), g.GOALS[0])


def test_without_rnea_the_one_sample_goals_are_unmeasured_and_not_met():
    r = _figures()
    del r["timings"]["rnea"]
    r["rnea_missing"] = "pinocchio not installed"
    lines = g.goals_lines(r)
    assert any("not measured (pinocchio not installed)" in ln for ln in lines)
    for goal in g.GOALS:
        row = _row(lines, goal)
        if goal.den == "rnea":
            assert row.endswith("| not measured | <= " + f"{goal.bound:g}x | **not met** (unmeasured) |"), row
        else:
            assert row.endswith("| **met** |"), row
    n, batch = len(g.GOALS), sum(goal.den != "rnea" for goal in g.GOALS)
    assert f"{batch} of {n} goals met (judged on the medians)." in lines


def test_the_scaling_report_carries_the_goals_and_the_rows(tmp_path):
    from exo_bench.bench.perf.reports.scaling import scaling

    r = _figures(inverse_checked=0.31)
    goals_row = {"group": "issue35-goals", "method": "(issue 35 goals)", "median": 0.0, "call_overhead": r}
    rows = [
        {"group": "overhead-exo5-3d", "method": k, "median": v, "samples": 10_000 if k in g.BATCH else 1}
        for k, v in r["timings"].items()
    ]
    inverse = {"group": "inverse-per-call-3d", "method": "pin.rnea (bare)", "mechanism": "exo5-3d", "n": 5, "dim": 3}
    inverse.update(topology="exo5", batched=False, samples=1, median=RNEA, max_rel_err=1e-16)
    text = scaling(pd.DataFrame([goals_row, *rows, inverse]), [], "exo-bench bench", tmp_path / "scaling.png")
    assert "## Per call" in text  # the whole report, not its early return without inverse rows
    assert "## Issue 35: the cost of the public call" in text
    assert (
        "| one sample, default call (`check=True`) | 1.08 us | bare `pin.rnea` | 0.31x | <= 0.3x | **not met** |"
        in text
    )
    assert f"{len(g.GOALS) - 1} of {len(g.GOALS)} goals met (judged on the medians)." in text
    assert "| inverse_batch_unchecked | 500 us | 0.0143x |" in text  # 0.05 us per sample against 3.5 us
    assert scaling(pd.DataFrame([rows[0]]), [], "c", tmp_path / "s.png").count("The goals' row did not run.") == 1


def test_the_calls_of_a_round_are_stated():
    r = _figures()
    r["calls_per_round"] = {"rnea": 2000, "forward_checked": 14}
    assert "14 to 2,000 calls a round" in g.goals_lines(r)[2]
    r["calls_per_round"] = 2000  # one count for every call (the rows' first form)
    assert "2,000 calls a round for one sample" in g.goals_lines(r)[2]


def test_a_busy_machine_is_named():
    r = _figures()
    assert "Load average" not in g.goals_lines(r)[2]  # not recorded: nothing said
    r["load"] = {"load_1min": 3.1, "cpus": 2}
    assert (
        "Load average 3.10 on 2 CPUs as the timing ended: a busy machine, the figures are provisional."
        in (g.goals_lines(r)[2])
    )
    r["load"] = {"load_1min": 0.2, "cpus": 2}
    assert g.goals_lines(r)[2].endswith("Load average 0.20 on 2 CPUs as the timing ended.")


def test_the_fastest_rounds_ratios_are_stated_beside_and_do_not_judge():
    r = _figures(inverse_checked=0.6)
    r["fastest"] = dict(r["timings"], inverse_checked=0.2 * RNEA)
    lines = g.goals_lines(r)
    assert _row(lines, g.GOALS[0]).endswith("| 0.6x | <= 0.3x | **not met** |")
    (line,) = [ln for ln in lines if ln.startswith("The same ratios of the fastest rounds")]
    assert "one sample, default call (`check=True`) 0.2x;" in line
    assert f"{len(g.GOALS) - 1} of {len(g.GOALS)} goals met (judged on the medians)." in lines


def test_every_goal_compares_timed_calls():
    timed = set(g.ONE_SAMPLE) | set(g.BATCH)
    assert {k for goal in g.GOALS for k in (goal.num, goal.den)} | {x for _, k, d in g.ALSO for x in (k, d)} <= timed
    assert all((goal.num in g.BATCH) == (goal.den in g.BATCH) for goal in g.GOALS)  # batch against batch only


def test_rounds_alternate_the_order_of_the_timers():
    """No timer always runs first in a round: every other round runs them in reverse (a first call
    pays for waking the thread pool), and each timer is timed once a round (fake timers, no clock)."""
    from exo_bench.bench.perf.reports.goals_call_overhead import _round_times

    log: list[str] = []

    class Fake:
        def __init__(self, key):
            self.key = key

        def timeit(self, number):
            log.append(self.key)
            return float(number)

    seconds, number = _round_times({k: Fake(k) for k in "abc"}, 1, 4, 0.0)
    timed = log[len(log) - 12 :]  # after _calls_per_round's one call each
    assert timed == list("abccbaabccba")
    assert number == {"a": 1, "b": 1, "c": 1} and all(v == [1.0] * 4 for v in seconds.values())
