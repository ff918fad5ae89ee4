"""Peak memory of a large batch: 10^6 samples need a fixed working set, not one growing with the batch.

A prepared model evaluates a batch in chunks of ``chunk_samples`` (set by ``prepare`` from the
method's cost model, exo_bench/api/cost_model.py) into one preallocated result, so beyond its inputs and its
result a batch of any length needs one chunk's temporaries. Measured here with ``tracemalloc``
(numpy's arrays are traced; Pinocchio's ``Data`` is C++, is not, and is fixed per model) as the
growth of the traced peak during ``model.inverse_dynamics(q, qd, qdd)`` with validation on
(``check=True``, the CLI's path), minus the result's own bytes. ``extra_info`` holds
``peak_mb`` (the growth), ``working_set_mb`` (growth minus the result), ``result_mb``, ``chunk``
and the cost model's bound ``bound_mb``; the assertion is that the working set stays within the
model's one-chunk bound at every batch size, 10^6 samples included (and 10^6 samples unchunked
would need ``samples / chunk`` times as much).

Measured on a shared 2-core machine (``pytest bench/test_memory.py --sweep=full --benchmark-enable``;
indicative): exo5-3d, 10^6 samples, result 120 MB; working set matrix-factored 4.5 MB (0.4 s),
matrix 9.6 MB (7.6 s), recurrence 15.6 MB (10.4 s), pinocchio 26.8 MB (6.8 s): the same as or
within one chunk of their 10^4-sample working sets (1.3, 9.6, 15.7, 3.6 MB).

The timing is the same call without tracing (one round). In the quick profile (CI and the main
job) only ``matrix-factored`` runs 10^6 samples (about a second); the slower methods' 10^6 rows are
skipped with the reason, and run with ``--sweep=full``.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
import pytest

from exo_bench.api import prepare
from exo_bench.api.cost_model import estimate
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5

SAMPLES = (10_000, 1_000_000)
METHODS = ("matrix-factored", "matrix", "pinocchio", "recurrence")
QUICK_1E6 = ("matrix-factored",)  # the others take 10-40 s for 10^6 samples
_STATES: dict[int, tuple] = {}


def _states(mech, samples):
    if samples not in _STATES:
        _STATES.clear()  # hold one batch at a time (10^6 samples: 360 MB of inputs)
        _STATES[samples] = random_states(mech, samples, 11)
    return _STATES[samples]


@pytest.mark.parametrize("samples", SAMPLES)
@pytest.mark.parametrize("method", METHODS)
def test_peak_memory_of_a_batch(benchmark, sweep, method, samples):
    mech = exo5(3)
    if samples >= 10**6 and sweep.name == "quick" and method not in QUICK_1E6:
        est = estimate(mech, method, samples)
        pytest.skip(
            f"{method}: 10^6 samples take about {est.seconds:.0f} s (exo_bench/api/cost_model.py), too slow for "
            "the quick profile; run with --sweep=full"
        )
    benchmark.group = "memory-exo5-3d"
    q, qd, qdd = _states(mech, samples)
    model = prepare(mech, method)
    model.inverse_dynamics(q[:2], qd[:2], qdd[:2])  # first call: Data, caches
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        before, _ = tracemalloc.get_traced_memory()
        tau = model.inverse_dynamics(q, qd, qdd)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    grown = peak - before
    working = grown - tau.nbytes
    bound = estimate(mech, method, samples).chunk_bytes
    chunk = model.chunk_samples
    benchmark.extra_info.update(
        method=method,
        samples=samples,
        mechanism=mech.name,
        n=mech.nlinks,
        dim=mech.dim,
        batched=True,  # every row of the suite has it (bench_reports filters on it)
        peak_mb=grown / 1e6,
        working_set_mb=working / 1e6,
        result_mb=tau.nbytes / 1e6,
        chunk=chunk,
        bound_mb=bound / 1e6,
    )
    assert np.isfinite(tau).all()
    assert working <= bound, (
        f"{method}, {samples} samples: working set {working / 1e6:.1f} MB > the cost model's "
        f"one-chunk bound {bound / 1e6:.1f} MB (chunk {chunk})"
    )
    del tau
    t0 = time.perf_counter()
    benchmark.pedantic(model.inverse_dynamics, args=(q, qd, qdd), rounds=1, iterations=1)
    benchmark.extra_info["seconds"] = time.perf_counter() - t0
