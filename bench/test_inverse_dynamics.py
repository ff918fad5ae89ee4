"""Numeric inverse dynamics through prepared models, batched and per call, for every method, with
its error against the 50-digit reference in ``extra_info`` and ASSERTED (one table for error
against run time, one for scaling in n, one for the wrapper's own cost).

Longer than the project's 400 lines on purpose: the distributed sweep keys its rows (and their
checkpoints) by file and model (bench/perf/rows.py), so per call and batched for one model, which
the reports divide by each other, stay one row of one file.

Rows are parametrized by ``method, kernel, n, dim, topology`` (explicit, readable parameters);
``extra_info["method"]`` is the row's name, which says what runs:

* every registered method, prepared once outside the timing (``exo_bench.prepare``); the matrix
  family's compiled methods twice, ``matrix-factored (numba)`` and ``matrix-factored (numpy)``
  (option ``kernel``);
* ``pinocchio-parallel``: the ``pinocchio`` method prepared with the thread count that is fastest
  on this machine for the batch (``rneaInParallel`` with a ``ModelPool``, the G^T map one matmul over
  the batch), batched only; the thread count is in ``extra_info``;
* ``pin.rnea (bare)``: per call, ``pin.rnea`` on preallocated joint-coordinate arrays of the same
  Pinocchio model, without our G maps: Pinocchio's own cost;
* ``mj_rne (bare)`` and ``CalcInverseDynamics (bare)``: per call, the engine's own calls on
  preallocated joint-coordinate arrays (no G maps, no wrapper), as ``pin.rnea (bare)`` is for
  Pinocchio: the report gives each engine method's overhead over them;
* ``pydy-cython``: per call, PyDy's Cython code generator on the same composed equations
  (:mod:`exo_bench.bench.perf.peers`; skipped with the reason when pydy/cython are not installed);
* ``mujoco`` and ``drake`` (registered methods, extra ``[peers]``): a Python loop over samples into
  the engine, four binding calls per sample (MuJoCo: ``mj_kinematics``, ``mj_comPos``,
  ``mj_comVel``, ``mj_rne``; Drake: ``SetPositions``, ``SetVelocities``, ``CalcInverseDynamics``,
  ``CalcGravityGeneralizedForces``), so their per-call and batched costs are mostly that overhead
  at small n; batched up to the n where the projected batch fits ``inverse_budget``; skipped with the
  reason (printed) when the engine is not installed (:class:`exo_bench.models.runtime.prepared.MissingExtra`);
* group ``wrapper``: on exo5-3d, a prepared model's call with ``check=False`` next to the kernel
  it calls, so the report gives the wrapper's own per-call cost (call minus kernel);
* group ``compile``: the first call's compile time of each compiled kernel (a fresh numba cache
  in a subprocess) and its load time from numba's cache in a second process;
* group ``limit``: the flops and transcendental calls of one exo5-3d sample of the factored
  kernel and this CPU's measured scalar/SIMD rates (:mod:`exo_bench.bench.perf.roofline`).

Per call, every prepared model and PyDy write into a preallocated ``out`` (``check=False``): what a
controller's loop does.

**Error bound** (asserted, see ``_bound``): every method but ``matrix-paper`` computes the
generalised forces in float64 with O(dof) roundings per entry, so against the 50-digit reference
(exact up to its own final rounding) ``max|tau - ref| <= K * eps * dof * max|ref|`` with
``K = 16``. ``matrix-paper`` is eq. (18) as printed: in 3D with more than one link its error must be
LARGE (the misprints are real; a tiny error there would mean the printed formulas are not what
runs), and in 2D it is the closed forms and held to the same bound. PyDy evaluates the same
equations with the coefficients rounded to double once and cse: the same bound.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

from exo_bench.bench.perf import roofline as limit, peers
from exo_bench.api import METHODS, prepare
from exo_bench.api.cost_model import ResourceLimit
from exo_bench.bench.studies.study import reference
from exo_bench.bench.perf.profiles import current
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.runtime.prepared import PreparedModel
from exo_bench.models.mechanism.presets import chain, exo5

K = 16
EPS = float(np.finfo(float).eps)
PAPER_WRONG_3D = 1e-3  # the printed eq. (18) is off by far more than this in 3D (reports/errata.md)
#: Methods with the option ``kernel`` (the kernel objects of their MethodSpec): each is a row per value.
COMPILED = tuple(m for m, s in METHODS.items() if s.kernel_options)
BATCHED = (*METHODS, "pinocchio-parallel")
#: Per call, each engine's own calls on preallocated joint-coordinate arrays (no G maps, no wrapper):
#: the engine's cost, so that the report gives the method's overhead over it.
BARE = {"pin.rnea (bare)": "pinocchio", "mj_rne (bare)": "mujoco", "CalcInverseDynamics (bare)": "drake"}
PER_CALL = (*METHODS, *BARE, "pydy-cython")
_FAILED: dict[tuple, str] = {}


#: A batch projected above this many seconds is timed once (after its warm-up call), not three times.
SLOW_BATCH_SECONDS = 10.0


def row_name(method: str, kernel: str | None) -> str:
    """The row's name: the method, and the kernel where the method has the option."""
    return f"{method} ({kernel})" if kernel else method


def _mechanism(n, dim, topo):
    return exo5(3) if topo == "exo5" else chain(n, dim)


def _variants(methods):
    return [(m, k) for m in methods for k in (METHODS[m].kernel_options if m in COMPILED else (None,))]


def _cases(ns, methods, sw=None):
    cases = [(m, k, n, d, "chain") for d in (2, 3) for n in ns for m, k in _variants(methods)]
    cases += [(m, k, 5, 3, "exo5") for m, k in _variants(methods)]  # the paper's five-link model: the goal rows
    if sw is not None:  # batched: the scaling rows (3D chains), every method within its budget, then newton-euler alone
        cases += [(m, k, n, 3, "chain") for n in sw.scaling_n for m, k in _variants(methods)]
        cases += [(m, k, n, 3, "chain") for n in sw.newton_euler_n for m, k in _variants(["newton-euler"])]
    return cases


def batch_samples(sw, mech) -> int:
    """Samples of a batched row: the profile's, capped so that q, qd, qdd and tau take at most
    ``sw.array_bytes`` (n = 10,000 in 3D: 139 samples of 30,000 coordinates); per-sample costs are
    compared, so the cap changes no ratio beyond the per-call overhead it amortises less."""
    return int(max(1, min(sw.samples, sw.array_bytes // (4 * 8 * mech.dof))))


def pytest_generate_tests(metafunc):
    if "topology" not in metafunc.fixturenames:
        return
    sw = current(metafunc.config.getoption("--sweep"))
    batched = metafunc.function.__name__ == "test_inverse_batched"
    cases = _cases(sw.inverse_n, BATCHED, sw) if batched else _cases(sw.per_call_n, PER_CALL)
    metafunc.parametrize(
        "method,kernel,n,dim,topology",
        cases,
        ids=[
            f"{row_name(m, k).replace(' ', '')}-{'exo5' if t == 'exo5' else f'chain{n}'}-{d}d"
            for m, k, n, d, t in cases
        ],
    )


def _fastest_threads(mech, q, qd, qdd) -> tuple[int, dict]:
    """The ``threads`` of ``pinocchio`` that is fastest on this batch here (best of 3 per count),
    and the seconds of each count tried (2 up to twice the CPU count)."""
    cpus = os.cpu_count() or 1
    times = {}
    for t in sorted({2, cpus, 2 * cpus}):
        try:
            m = prepare(mech, "pinocchio", threads=t)
        except (MemoryError, ResourceLimit):  # one Data per thread does not fit (prepare's estimate, or the Data's)
            continue
        m.inverse_dynamics(q[:8], qd[:8], qdd[:8], check=False)
        best = np.inf
        for _ in range(3):
            t0 = time.perf_counter()
            m.inverse_dynamics(q, qd, qdd, check=False)
            best = min(best, time.perf_counter() - t0)
        times[t] = best
    return (min(times, key=lambda t: times[t]) if times else 2), times


def _prepare(method: str, kernel, mech, sw, batch=None):
    """The prepared model, outside the timing; over budget -> a skip with the reason, remembered."""
    key = (method, kernel, mech)
    if key in _FAILED:
        pytest.skip(_FAILED[key])
    base = {"pinocchio-parallel": "pinocchio", **BARE}.get(method, method)
    options = {"kernel": kernel} if kernel else {}
    if method == "pinocchio-parallel":
        options["threads"] = _fastest_threads(mech, *batch)[0] if batch is not None else 2
    if base == "lagrange":
        options["budget"] = sw.derive_budget
    try:
        return prepare(mech, base, **options)
    except Exception as e:  # noqa: BLE001
        reason = getattr(e, "skip_reason", None) or (str(e) if isinstance(e, MemoryError) else None)
        if not reason:
            raise
        _FAILED[key] = f"{method}: {reason}"
        print(f"skipped: {_FAILED[key]}")
        pytest.skip(_FAILED[key])


def _bound(method: str, mech, ref: np.ndarray) -> float:
    return K * EPS * mech.dof * float(np.abs(ref).max())


def check_error(benchmark, method, mech, q, qd, qdd, tau, subsample):
    """Record the error against the 50-digit reference in ``extra_info`` and assert its bound."""
    idx = np.unique(np.linspace(0, q.shape[0] - 1, subsample).round().astype(int))
    ref, label = reference(mech, q[idx], qd[idx], qdd[idx])
    err = np.abs(tau[idx] - ref)
    bound = _bound(method, mech, ref)
    scale = float(np.abs(ref).max())
    benchmark.extra_info.update(
        max_abs_err=float(err.max()),
        max_rel_err=float(err.max() / scale),
        bound_rel=bound / scale,
        reference=label,
        nonfinite=int(np.count_nonzero(~np.isfinite(tau))),
    )
    if method == "matrix-paper" and mech.dim == 3 and mech.nlinks > 1:
        assert not (err.max() <= PAPER_WRONG_3D * scale), (
            "matrix-paper (eq. 18 as printed) agrees with the reference in 3D: the printed formulas are not what runs"
        )
    else:
        assert np.isfinite(tau[idx]).all(), f"{method}: NaN/Inf in the forces"
        assert err.max() <= bound, (
            f"{method} on {mech.name}: error {err.max():.3e} > bound {bound:.3e} "
            f"(K={K} * eps * dof={mech.dof} * max|tau|)"
        )


def _info(benchmark, method, kernel, n, dim, topology, mech, **more):
    benchmark.extra_info.update(
        method=row_name(method, kernel),
        base_method=method,
        kernel=kernel or "",
        n=n,
        dim=dim,
        topology=topology,
        mechanism=mech.name,
        **more,
    )


def test_inverse_batched(benchmark, sweep, method, kernel, n, dim, topology):
    benchmark.group = f"inverse-batched-{dim}d"
    mech = _mechanism(n, dim, topology)
    samples = batch_samples(sweep, mech)
    if n > max(sweep.inverse_n):  # the scaling rows: the cost model first (a probe of an O(n^3) method takes minutes)
        from exo_bench.api.cost_model import estimate

        base = {"pinocchio-parallel": "pinocchio"}.get(method, method)
        est = estimate(mech, base, samples, {"kernel": kernel} if kernel else {}).seconds
        if est > 10 * sweep.inverse_budget:
            pytest.skip(
                f"{row_name(method, kernel)} n={n} {dim}D: over budget, projected by the cost model "
                f"(exo_bench/api/cost_model.py) {est:.0f} s per batch of {samples} > 10 x {sweep.inverse_budget:g} s"
            )
    mo = smooth_random_motion(mech, np.linspace(0.0, 10.0, samples), seed=n)
    q, qd, qdd = mo.q, mo.qd, mo.qdd
    model = _prepare(method, kernel, mech, sweep, batch=(q, qd, qdd))
    # one sample first (twice: the first call pays caches and JIT): at n = 1000 a 50-sample probe of
    # an O(n^3) method would take minutes
    model.inverse_dynamics(q[:1], qd[:1], qdd[:1], check=False)
    t0 = time.perf_counter()
    model.inverse_dynamics(q[:1], qd[:1], qdd[:1], check=False)
    one = time.perf_counter() - t0
    if one * samples > 10 * sweep.inverse_budget:
        pytest.skip(
            f"{row_name(method, kernel)} n={n} {dim}D: over budget, projected from one sample "
            f"{one * samples:.1f} s per batch of {samples} > {sweep.inverse_budget:g} s"
        )
    probe = min(50, samples)
    model.inverse_dynamics(q[:probe], qd[:probe], qdd[:probe], check=False)  # first-call costs (caches, JIT)
    t0 = time.perf_counter()
    model.inverse_dynamics(q[:probe], qd[:probe], qdd[:probe], check=False)
    projected = (time.perf_counter() - t0) * samples / probe
    if projected > sweep.inverse_budget:
        pytest.skip(
            f"{row_name(method, kernel)} n={n} {dim}D: over budget, projected {projected:.1f} s per batch of "
            f"{samples} > {sweep.inverse_budget:g} s"
        )
    model.inverse_dynamics(q, qd, qdd, check=False)  # the parallel driver's first use: the warm-up round
    # three rounds at least, one for a batch of minutes: five such batches per method (warm-up included)
    # took the 3D n = 500 row over its row budget of 1800 s in the full sweep, which lost every method's row
    rounds = 1 if projected > SLOW_BATCH_SECONDS else max(3, min(20, int(2.0 / max(projected, 1e-9))))
    _info(
        benchmark,
        method,
        kernel,
        n,
        dim,
        topology,
        mech,
        samples=samples,
        batched=True,
        threads=model.options.get("threads", ""),
    )
    tau = benchmark.pedantic(
        model.inverse_dynamics, args=(q, qd, qdd), kwargs={"check": False}, rounds=rounds, iterations=1, warmup_rounds=0
    )
    check_error(benchmark, method, mech, q, qd, qdd, np.asarray(tau), sweep.error_subsample)


def _bare_rnea(model, q, qd, qdd):
    """``pin.rnea`` on preallocated joint-coordinate arrays (no G maps, no checks)."""
    import pinocchio as pin

    qj, vj, aj = (np.ascontiguousarray(x @ model.GT) for x in (q, qd, qdd))
    data = model.pin_model.createData()
    pm = model.pin_model
    return (lambda: pin.rnea(pm, data, qj, vj, aj)), (lambda tau_joint: tau_joint @ model.G)


def _bare_engine(method, model, q, qd, qdd):
    """The engine's calls of one sample on preallocated joint-coordinate arrays, without the G maps
    or the prepared model's wrapper: MuJoCo's four stages into a preallocated result; Drake's state
    set and its inverse dynamics minus gravity (the state is set on every call, as the method does)."""
    qj, vj, aj = (np.ascontiguousarray(x @ model.GT) for x in (q, qd, qdd))
    if method == "mj_rne (bare)":
        import mujoco

        m, d = model.mj_model, model.data
        d.qpos[:], d.qvel[:], d.qacc[:] = qj, vj, aj
        res = np.empty(m.nv)

        def call():
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            mujoco.mj_comVel(m, d)
            mujoco.mj_rne(m, d, 1, res)
            return res

        return call, (lambda tau_joint: tau_joint @ model.G)
    plant = model.plant
    ctx, forces = model._scratch()

    def call():
        plant.SetPositions(ctx, qj)
        plant.SetVelocities(ctx, vj)
        return plant.CalcInverseDynamics(ctx, aj, forces) - plant.CalcGravityGeneralizedForces(ctx)

    return call, (lambda tau_joint: tau_joint @ model.G)


def _pydy(mech, sw):
    """PyDy's compiled function of the composed equations; a skip with the reason when it cannot run."""
    why = peers.missing()
    if why:
        print(f"skipped: {why}")
        pytest.skip(why)
    if mech.name != "exo5-3d" and mech.nlinks not in sw.pydy_n:
        pytest.skip(
            f"pydy-cython: n={mech.nlinks} not generated in the {sw.name} profile (composing and compiling "
            f"C grows fast with n: minutes at n = 20 in 3D); profile pydy_n = {sw.pydy_n}"
        )
    return peers.pydy_cython(mech)


def test_inverse_per_call(benchmark, sweep, method, kernel, n, dim, topology):
    benchmark.group = f"inverse-per-call-{dim}d"
    mech = _mechanism(n, dim, topology)
    mo = smooth_random_motion(mech, np.linspace(0.0, 10.0, 8), seed=n)
    q, qd, qdd = mo.q[0].copy(), mo.qd[0].copy(), mo.qdd[0].copy()
    out = np.empty(mech.dof)
    _info(benchmark, method, kernel, n, dim, topology, mech, samples=1, batched=False)
    if method == "pydy-cython":
        f = _pydy(mech, sweep)
        benchmark.extra_info.update(generate_seconds=f.seconds)
        tau = benchmark(f.call, q, qd, qdd, out).copy()
    elif method == "pin.rnea (bare)":
        call, to_paper = _bare_rnea(_prepare(method, kernel, mech, sweep), q, qd, qdd)
        tau = to_paper(benchmark(call))
    elif method in BARE:
        call, to_paper = _bare_engine(method, _prepare(method, kernel, mech, sweep), q, qd, qdd)
        tau = to_paper(benchmark(call).copy())
    else:
        model = _prepare(method, kernel, mech, sweep)
        model.inverse_dynamics(q, qd, qdd, check=False, out=out)
        tau = benchmark(model.inverse_dynamics, q, qd, qdd, check=False, out=out).copy()
    check_error(benchmark, method, mech, q[None], qd[None], qdd[None], np.asarray(tau)[None], 1)


WRAPPED = ("matrix-factored", "matrix", "pinocchio")


class _NullKernel(PreparedModel):
    """A prepared model whose kernel does no work (returns ``qdd``): its call with ``check=False``
    costs the wrapper alone, without the noise of a real kernel's time."""

    method = "null-kernel"

    def _inverse_dynamics(self, q, qd, qdd):
        return qdd


@pytest.mark.parametrize("part", ["call", "kernel"])
def test_wrapper_alone(benchmark, part):
    mech = exo5(3)
    benchmark.group = "wrapper-exo5-3d"
    model = _NullKernel(mech)
    q = qd = qdd = np.zeros(mech.dof)
    Q = q[None]
    benchmark.extra_info.update(
        method="(wrapper alone)", part=part, mechanism=mech.name, samples=1, batched=False, n=5, dim=3
    )
    if part == "call":
        out = benchmark(model.inverse_dynamics, q, qd, qdd, check=False)
        assert out.shape == (mech.dof,)  # the wrapper returns one sample for one sample
    else:
        out = benchmark(model._inverse_dynamics, Q, Q, Q)
        assert out.shape == (1, mech.dof)


@pytest.mark.parametrize("part", ["call", "kernel"])
@pytest.mark.parametrize("method", WRAPPED)
def test_wrapper_overhead(benchmark, sweep, method, part):
    """exo5-3d, one sample: the prepared model's call (``check=False``, ``out=``) and the kernel it
    calls with the same arrays (the compiled kernel itself for ``kernel="numba"``); the report's
    wrapper cost is the difference of the two medians."""
    mech = exo5(3)
    benchmark.group = "wrapper-exo5-3d"
    mo = smooth_random_motion(mech, np.linspace(0.0, 1.0, 4), seed=5)
    model = _prepare(method, None, mech, sweep)
    kernel = model.options.get("kernel")
    q, qd, qdd = mo.q[0].copy(), mo.qd[0].copy(), mo.qdd[0].copy()
    Q, QD, QDD = q[None], qd[None], qdd[None]
    out = np.empty(mech.dof)
    benchmark.extra_info.update(
        method=row_name(method, kernel), part=part, mechanism=mech.name, samples=1, batched=False, n=5, dim=3
    )
    if part == "call":
        tau = benchmark(model.inverse_dynamics, q, qd, qdd, check=False, out=out).copy()
    elif any(k.compiled for k in METHODS[method].kernels_for(kernel)):
        args = model.kernel_args
        benchmark(model.serial_kernel, *args, q, qd, qdd, out)  # the compiled kernel alone
        tau = out.copy()
    else:
        tau = benchmark(model._inverse_dynamics, Q, QD, QDD)[0]  # the method's own work on (1, dof)
    check_error(benchmark, method, mech, Q, QD, QDD, np.asarray(tau)[None], 1)


_COMPILE_PROBE = """
import json, sys, time
t0 = time.perf_counter()
import numpy as np
from exo_bench import prepare, presets
from exo_bench.matrix_method.numba_kernels import common as compiled
from exo_bench.models.machine import numba_runtime
t_import = time.perf_counter() - t0
out = {"import_seconds": t_import}
for method in sys.argv[1].split(","):
    m = prepare(presets.exo5(dim=3), method)
    q = np.full(m.dof, 0.5)
    Q = np.full((numba_runtime.PARALLEL_MIN_SAMPLES, m.dof), 0.5)
    o, O = np.empty(m.dof), np.empty(Q.size)
    args = {"serial": (*m.kernel_args, q, q, q, o), "parallel": (*m.kernel_args, Q.ravel(), Q.ravel(), Q.ravel(), O)}
    out[method] = compiled.compile_times({"serial": m.serial_kernel, "parallel": m.parallel_kernel}, args)
print(json.dumps(out))
"""


def _compile_probe(methods, env) -> dict:
    r = subprocess.run(
        [sys.executable, "-c", _COMPILE_PROBE, ",".join(methods)], env=env, capture_output=True, text=True, timeout=1200
    )
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_compile_time(benchmark, tmp_path):
    """The first call's compile time of each compiled kernel on exo5-3d (serial and parallel
    drivers) in a fresh process with an empty numba cache, then the same first calls in a second
    process that loads them from the cache (timed runs only: compiling every kernel costs half a
    minute, too much for CI)."""
    benchmark.group = "compile"
    if benchmark.disabled:
        pytest.skip(
            "compile time: measured when the benchmarks are timed (exo-bench bench); numba's cache across "
            "processes is tested by tests/test_compiled.py"
        )
    methods = COMPILED
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    cold = _compile_probe(methods, env)
    warm = _compile_probe(methods, env)
    for m in methods:
        for driver in ("serial", "parallel"):
            assert cold[m][driver]["cache_misses"] >= 1 and cold[m][driver]["cache_hits"] == 0, (m, driver, cold)
            assert warm[m][driver]["cache_hits"] >= 1 and warm[m][driver]["cache_misses"] == 0, (m, driver, warm)
    benchmark.extra_info.update(
        method="(compile)",
        mechanism="exo5-3d",
        samples=1,
        batched=False,
        n=5,
        dim=3,
        compile={
            m: {
                d: {"first_call_s": cold[m][d]["seconds"], "from_cache_s": warm[m][d]["seconds"]}
                for d in ("serial", "parallel")
            }
            for m in methods
        },
        import_seconds=warm["import_seconds"],
    )
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


def test_limit(benchmark):
    """The arithmetic of one exo5-3d sample of the factored kernel, counted from its code, and
    this CPU's multiply-add and sin rates (bench/perf/roofline.py); the report turns them into a time."""
    benchmark.group = "limit"
    mech = exo5(3)
    q, qd, qdd = (
        x[0].copy()
        for x in (lambda m: (m.q, m.qd, m.qdd))(smooth_random_motion(mech, np.linspace(0.0, 1.0, 2), seed=5))
    )
    count, tau = limit.count_factored(mech, q, qd, qdd)
    # what was counted is what the compiled kernel computes: the same forces, to the last bit
    assert np.array_equal(tau, prepare(mech, "matrix-factored").inverse_dynamics(q, qd, qdd, check=False))
    assert count["trig"] == 4 * mech.nlinks  # cos, sin of phi_j and of psi_j
    rates = limit.throughput()
    import numba

    benchmark.extra_info.update(
        method="(limit)",
        mechanism=mech.name,
        samples=1,
        batched=False,
        n=5,
        dim=3,
        count=count,
        rates=rates,
        estimate=limit.estimate(count, rates),
        numba_threads=numba.get_num_threads(),
    )
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
