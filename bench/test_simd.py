"""Issue 23's goals as one benchmark row (bench/perf/reports/simd_goals.py measures every figure in this process,
the threading trap in two subprocesses): exo5-3d batched at one and two threads from the public
call, against the counted limit and Pinocchio's best batched path; one sample per call against
PyDy's Cython code; the batch after a user's code started numba's OpenMP threads. The errors
against the 50-digit reference are asserted; the goals are reported (reports/scaling.md, "Issue
23"), never asserted: timing goals belong to a quiet machine, not to a test.
"""

from __future__ import annotations

import pytest

from exo_bench.bench.perf.reports import simd_goals


def test_issue23_goals(benchmark, sweep):
    benchmark.group = "simd-goals"
    if benchmark.disabled:
        pytest.skip(
            "issue 23's goals: measured when the benchmarks are timed (exo-bench bench, or "
            "python -m exo_bench.bench.perf.reports.simd_goals); the kernels' agreement is tested in tests/"
        )
    samples = 10_000 if sweep.samples >= 10_000 else sweep.samples
    r = simd_goals.measure(samples=samples)
    assert r["batched_err"] <= r["err_bound"], r
    assert r["per_call_err"] <= r["err_bound"], r
    if "pydy_err" in r:
        assert r["pydy_err"] <= r["err_bound"], r
    benchmark.extra_info.update(
        method="(issue 23 goals)", mechanism=r["mechanism"], samples=samples, batched=True, n=5, dim=3, simd_goals=r
    )
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
