"""Issue 23's goal lines (bench/perf/reports/simd_goals.py :func:`goals_lines`): the batched goals are
stated at 10,000 samples, so a smaller run (the main job's quick profile, 1,000 samples) reports its
figures against them without a verdict, and says where they are judged; at the goals' size each goal
is met or not by its own figure."""

from __future__ import annotations

import pytest

from exo_bench.bench.perf.reports import simd_goals as g


def _figures(samples: int, scale: float = 1.0) -> dict:
    """Figures as :func:`simd_goals.measure` returns them; ``scale`` multiplies the batched times
    (1: every goal met; 4: every batched goal missed)."""
    return {
        "samples": samples,
        "reference": "Lagrange, mpmath 50 digits",
        "batched_err": 1e-13,
        "per_call_err": 6e-14,
        "err_bound": 3e-11,
        "batched_1t": 0.045 * scale,
        "batched_2t": 0.036 * scale,
        "count": {"flops": 885},
        "limit_1t_us": 0.025,
        "limit_2t_us": 0.0125,
        "rates": {"simd_flops_per_s": 35.6e9},
        "newton_euler_batched_1t": 0.058 * scale,
        "newton_euler_limit_1t_us": 0.025,
        "newton_euler_count": {"flops": 887},
        "newton_euler_batched_err": 1e-13,
        "per_sample_kernel_1t": 0.17,
        "pinocchio_best": "pinocchio_2t",
        "pinocchio_best_us": 3.0,
        "per_call": 0.26,
        "pydy_per_call": 0.77,
        "trap": {
            "ratio": 0.96,
            "normal": {"seconds": 3e-4},
            "omp-first": {"seconds": 2.9e-4, "layer": "omp", "threads": 2},
        },
    }


BATCHED_GOALS = 4  # the faster method's batch, matrix-factored's batch, its counted limit, Pinocchio


def test_at_the_goals_size_each_goal_is_judged():
    met = "\n".join(g.goals_lines(_figures(g.GOAL_SAMPLES)))
    assert met.count("**met**") == BATCHED_GOALS + 3 and "**not met**" not in met  # + per call, PyDy, trap
    missed = "\n".join(g.goals_lines(_figures(g.GOAL_SAMPLES, scale=4.0)))
    assert missed.count("**not met**") == BATCHED_GOALS and "not judged" not in missed


@pytest.mark.parametrize("scale, word", [(1.0, "within"), (4.0, "outside")])
def test_a_quick_run_reports_the_batched_goals_without_a_verdict(scale, word):
    lines = g.goals_lines(_figures(1_000, scale))
    text = "\n".join(lines)
    assert text.count(f"{word} it at 1,000 samples, not judged") == BATCHED_GOALS
    assert "**not met**" not in text and text.count("**met**") == 3  # per call, PyDy, trap: not batch-sized
    said = next(line for line in lines if line.startswith("The batched goals are stated at 10,000 samples"))
    assert "this run (the quick profile) has 1,000" in said and "reports/full/scaling.md" in said
