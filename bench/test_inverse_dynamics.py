"""Numeric inverse dynamics, batched and per sample, for every method, with its error against
the 50-digit reference in ``extra_info`` (one table for error against run time)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from exo_bench.bench.methods import METHODS, get_method
from exo_bench.bench.reference import reference
from exo_bench.bench.sweep import current
from exo_bench.models import pinocchio_backend
from exo_bench.models.motion import smooth_random_motion
from exo_bench.models.presets import chain, exo5

NUMERIC = ("matrix", "matrix-paper", "recurrence", "lagrange", "pinocchio", "pinocchio-parallel")
_FAILED: dict[tuple, str] = {}


def _method(name):
    if name == "pinocchio-parallel":
        return lambda m, q, qd, qdd: pinocchio_backend.inverse_dynamics_parallel(m, q, qd, qdd, threads=2)
    if name not in METHODS:
        pytest.skip(f"{name}: not registered in bench/methods.py")
    return get_method(name)


def _cases(sw):
    cases = [(m, n, d, "chain") for d in (2, 3) for n in sw.inverse_n for m in NUMERIC]
    cases += [(m, 5, 3, "exo5") for m in NUMERIC]  # the paper's five-link model: the goal row
    return cases


def pytest_generate_tests(metafunc):
    for name in ("case", "single_case"):
        if name in metafunc.fixturenames:
            cases = _cases(current(metafunc.config.getoption("--sweep")))
            if name == "single_case":  # rneaInParallel is a batched entry point only
                cases = [c for c in cases if c[0] != "pinocchio-parallel"]
            metafunc.parametrize(name, cases, ids=[f"{m}-{t}{n}-{d}d" for m, n, d, t in cases])


def _setup(case, samples, sw):
    method, n, dim, topo = case
    mech = exo5(3) if topo == "exo5" else chain(n, dim)
    t = np.linspace(0.0, 10.0, samples)
    mo = smooth_random_motion(mech, t, seed=n)
    fn = _method(method)
    key = (method, mech)
    if key in _FAILED:
        pytest.skip(_FAILED[key])
    try:
        if method == "lagrange":  # derive within the sweep's budget (a skip with the reason otherwise)
            from exo_bench.lagrange import derive
            derive(mech, budget=sw.derive_budget)
        fn(mech, mo.q[:2], mo.qd[:2], mo.qdd[:2])  # build models / derive once, outside the timing
    except Exception as e:  # noqa: BLE001
        reason = getattr(e, "skip_reason", None)
        if not reason:
            raise
        _FAILED[key] = f"{method}: {reason}"
        pytest.skip(_FAILED[key])
    return mech, mo, fn


def _errors(benchmark, mech, mo, tau, subsample):
    idx = np.unique(np.linspace(0, mo.q.shape[0] - 1, subsample).round().astype(int))
    ref, label = reference(mech, mo.q[idx], mo.qd[idx], mo.qdd[idx])
    err = np.abs(tau[idx] - ref)
    benchmark.extra_info.update(max_abs_err=float(err.max()), max_rel_err=float(err.max() / np.abs(ref).max()),
                                reference=label, nonfinite=int(np.count_nonzero(~np.isfinite(tau))))


def test_inverse_batched(benchmark, sweep, case):
    method, n, dim, topo = case
    benchmark.group = f"inverse-batched-{dim}d"
    mech, mo, fn = _setup(case, sweep.samples, sweep)
    probe = min(50, sweep.samples)
    t0 = time.perf_counter()
    fn(mech, mo.q[:probe], mo.qd[:probe], mo.qdd[:probe])
    projected = (time.perf_counter() - t0) * sweep.samples / probe
    if projected > sweep.inverse_budget:
        pytest.skip(f"{method} n={n} {dim}D: over budget, projected {projected:.1f} s per batch of "
                    f"{sweep.samples} > {sweep.inverse_budget:g} s")
    rounds = max(1, min(20, int(2.0 / max(projected, 1e-9))))
    benchmark.extra_info.update(method=method, n=n, dim=dim, mechanism=mech.name, samples=sweep.samples,
                                batched=True)
    tau = benchmark.pedantic(fn, args=(mech, mo.q, mo.qd, mo.qdd), rounds=rounds, iterations=1, warmup_rounds=1)
    _errors(benchmark, mech, mo, np.asarray(tau), sweep.error_subsample)


def test_inverse_per_sample(benchmark, sweep, single_case):
    method, n, dim, topo = single_case
    benchmark.group = f"inverse-per-sample-{dim}d"
    mech, mo, fn = _setup(single_case, 8, sweep)
    benchmark.extra_info.update(method=method, n=n, dim=dim, mechanism=mech.name, samples=1, batched=False)
    tau = benchmark(fn, mech, mo.q[:1], mo.qd[:1], mo.qdd[:1])
    _errors(benchmark, mech, mo, np.vstack([np.asarray(tau)] * mo.q.shape[0]), 1)
