"""Issue 35's goals as benchmark rows: what the public call costs on top of its kernel, on exo5-3d.

* ``test_issue35_goals``: one row that times every call of the goals interleaved in this process
  (bench/perf/reports/goals_call_overhead.py :func:`measure`), the ratios the report judges
  (reports/scaling.md, "Issue 35"), with issue 47's two rows of the public ``model.derivatives.inverse_dynamics``
  of one sample. The agreement of every timed result is asserted (one-sample inverse dynamics against the
  50-digit reference, forward dynamics' backward error, the derivatives' ``M`` against the mass matrix); the speed
  goals are reported, never asserted: timing goals belong to a quiet machine, not to a test.
* ``test_call[...]``: each of the same calls alone as a pytest-benchmark row (group
  ``overhead-exo5-3d``), for ``py.test-benchmark compare`` across commits.

Only the public API is called (``exo_bench.prepare`` and the prepared model's methods), so the
rows time whatever call path the library has.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.bench.perf.reports import goals_call_overhead as goals


def _samples(sweep) -> int:
    return min(10_000, sweep.samples)


#: Why the goals' row does nothing in an untimed run (pytest's default here: --benchmark-disable).
UNTIMED = (
    "issue 35's goals: measured when the benchmarks are timed (exo-bench bench, or "
    "python -m exo_bench.bench.perf.reports.goals_call_overhead)"
)


def test_issue35_goals(benchmark, sweep):
    if benchmark.disabled:
        pytest.skip(UNTIMED)
    pytest.importorskip("pinocchio", reason="the one-sample goals are ratios to bare pin.rnea")
    benchmark.group = "issue35-goals"
    r = goals.measure(samples=_samples(sweep))
    assert all(e <= r["err_bound"] for e in r["inverse_err"].values()), r["inverse_err"]
    assert all(e <= b for e, b in r["forward_backward_err"].values()), r["forward_backward_err"]
    assert r["inverse_batch_diff"] <= r["err_bound"], r["inverse_batch_diff"]
    assert all(e <= 1e-12 for e in r["derivatives_mass_err"].values()), r["derivatives_mass_err"]  # relative
    benchmark.extra_info.update(
        method="(issue 35 goals)", mechanism=r["mechanism"], samples=r["samples"], n=5, dim=3, call_overhead=r
    )
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


@pytest.fixture(scope="module")
def candidates(sweep):
    return goals.calls(_samples(sweep))


@pytest.mark.parametrize("call", [*goals.ONE_SAMPLE, *goals.BATCH])
def test_call(benchmark, sweep, candidates, call):
    c, states = candidates
    if call not in c:  # only the bare rnea may be missing (no pinocchio); any other call is a bug
        assert call == "rnea" and "rnea_missing" in states, f"{call}: not among goals.calls()"
        pytest.skip(states["rnea_missing"])
    benchmark.group = "overhead-exo5-3d"
    one = call in goals.ONE_SAMPLE
    benchmark.extra_info.update(
        method=call, mechanism=states["mech"].name, samples=1 if one else _samples(sweep), n=5, dim=3
    )
    got = np.asarray(benchmark(c[call].fn, *c[call].args, **c[call].kwargs))
    assert np.isfinite(got).all()
