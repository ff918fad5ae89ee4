"""Forward dynamics per sample: ``newton-euler``'s O(n) passes against the dense routes, with the
backward error ASSERTED and the memory per sample recorded.

Rows (``extra_info["method"]``), parametrized by ``method, kernel, n, dim, topology`` like
bench/test_inverse_dynamics.py, so that the distributed sweep groups them by (dim, n) into rows of
one host (bench/perf/rows.py):

* ``newton-euler (numba)`` / ``newton-euler (numpy)``: ``forward_dynamics``: ``r'' = M_r^-1 (J^-T tau
  - g_r)`` with ``M_r`` factored once, then ``J^-1``; O(n) per sample;
* ``pinocchio (CRBA + Cholesky)``: Pinocchio's CRBA and ``nonLinearEffects``, then the Cholesky
  solve of :meth:`exo_bench.models.runtime.prepared.PreparedModel.forward_dynamics` (its ABA refuses mimic joints);
* ``matrix-factored (numba) + solve``: ``M`` and ``h`` derived from the compiled inverse dynamics
  (``dof + 2`` rows per sample), then the same Cholesky solve;
* ``matrix (numba) + solve``: the matrix method's own ``A, B, Lambda`` blocks, then the solve.

Batched (one call on ``samples`` samples, ``check=False``), 3D chains and exo5-3d; ``n`` from the
profile's ``forward_n`` and, for newton-euler alone, ``newton_euler_n`` (n = 10,000 in the full
profile). A row whose projected time exceeds the profile's budget is skipped with the reason.

**Error bound** (asserted): the solve is backward stable, so the accelerations it returns satisfy
the equations of motion to rounding. Checked with newton-euler's inverse dynamics (O(n), itself
held to the 50-digit reference by tests/test_newton_euler.py):
``|ID(q, qd, qdd') - tau| <= K eps dof (|tau| + |M qdd'| + |h|)`` (max norms, ``K = 16``), with
``M qdd' = ID(q, 0, qdd') - ID(q, 0, 0)``. The forward error ``|qdd' - qdd|`` against the
accelerations that produced ``tau`` depends on ``cond(M)`` (tests/test_forward_property.py) and is
recorded, not asserted.

**Memory per sample**: the growth of the traced peak (``tracemalloc``: numpy's arrays, the result's
``8 dof`` bytes per sample included; numba's per-block scratch, O(n), is not traced) during one
untimed call, divided by the samples, and the process's peak resident set (``ru_maxrss``) after
the row. Measured on the shared machine at n = 10,000 (139 samples): newton-euler (numba) 249 kB
per sample, of which the result is 240 kB; a fresh process running inverse and forward dynamics
peaks at 420 MB (``test_newton_euler_memory``).
"""

from __future__ import annotations

import resource
import time
import tracemalloc

import numpy as np
import pytest

from exo_bench.api import prepare
from exo_bench.bench.perf.profiles import current
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, exo5

K = 16
EPS = float(np.finfo(float).eps)
#: row method -> (registered method, kernel option)
ROUTES = {
    "newton-euler (numba)": ("newton-euler", "numba"),
    "newton-euler (numpy)": ("newton-euler", "numpy"),
    "pinocchio (CRBA + Cholesky)": ("pinocchio", None),
    "matrix-factored (numba) + solve": ("matrix-factored", "numba"),
    "matrix (numba) + solve": ("matrix", "numba"),
}
NEWTON_EULER = ("newton-euler (numba)", "newton-euler (numpy)")
#: Samples per batched call (capped by the profile's array bytes, as in bench/test_inverse_dynamics.py).
SAMPLES = {"quick": 200, "full": 2000}


def _cases(sw):
    cases = [(m, None, n, 3, "chain") for n in sw.forward_n for m in ROUTES]
    cases += [(m, None, 5, 3, "exo5") for m in ROUTES]
    cases += [(m, None, n, 3, "chain") for n in sw.newton_euler_n for m in NEWTON_EULER]
    return cases


def pytest_generate_tests(metafunc):
    if "topology" not in metafunc.fixturenames:
        return
    sw = current(metafunc.config.getoption("--sweep"))
    if metafunc.function.__name__ == "test_newton_euler_memory":
        mem = _memory_cases(sw)
        metafunc.parametrize("n,dim,topology", mem, ids=[f"chain{c[0]}-3d" for c in mem])
        return
    cases = _cases(sw)
    metafunc.parametrize(
        "method,kernel,n,dim,topology",
        cases,
        ids=[f"{m.replace(' ', '')}-{'exo5' if t == 'exo5' else f'chain{n}'}-{d}d" for m, _, n, d, t in cases],
    )


def _prepare(method, mech):
    base, kernel = ROUTES[method]
    try:
        return prepare(mech, base, **({"kernel": kernel} if kernel else {}))
    except MemoryError as e:  # Pinocchio's Data (32 nv^3 bytes) does not fit
        pytest.skip(f"{method} n={mech.nlinks}: {e}")


def test_forward_batched(benchmark, sweep, method, kernel, n, dim, topology):
    benchmark.group = f"forward-batched-{dim}d"
    mech = exo5(3) if topology == "exo5" else chain(n, dim)
    samples = int(max(1, min(SAMPLES[sweep.name], sweep.array_bytes // (4 * 8 * mech.dof))))
    q, qd, qdd = random_states(mech, samples, seed=n)
    ne = prepare(mech, "newton-euler")
    tau = ne.inverse_dynamics(q, qd, qdd, check=False)
    model = _prepare(method, mech)
    model.forward_dynamics(q[:1], qd[:1], tau[:1], check=False)  # first-call costs (JIT, caches)
    t0 = time.perf_counter()
    model.forward_dynamics(q[:1], qd[:1], tau[:1], check=False)
    projected = (time.perf_counter() - t0) * samples
    if projected > sweep.inverse_budget:
        pytest.skip(
            f"{method} n={n} {dim}D: over budget, projected {projected:.1f} s per batch of {samples} "
            f"> {sweep.inverse_budget:g} s"
        )
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    model.forward_dynamics(q, qd, tau, check=False)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    rounds = max(3, min(20, int(2.0 / max(projected, 1e-9))))
    benchmark.extra_info.update(
        method=method,
        base_method=ROUTES[method][0],
        kernel=ROUTES[method][1] or "",
        n=n,
        dim=dim,
        topology=topology,
        mechanism=mech.name,
        samples=samples,
        batched=True,
        traced_bytes_per_sample=peak / samples,
    )
    got = np.asarray(
        benchmark.pedantic(
            model.forward_dynamics,
            args=(q, qd, tau),
            kwargs={"check": False},
            rounds=rounds,
            iterations=1,
            warmup_rounds=1,
        )
    )
    idx = np.unique(np.linspace(0, samples - 1, min(samples, 64)).round().astype(int))
    residual = ne.inverse_dynamics(q[idx], qd[idx], got[idx], check=False) - tau[idx]
    zero = np.zeros_like(q[idx])
    h = ne.inverse_dynamics(q[idx], qd[idx], zero, check=False)
    mq = ne.inverse_dynamics(q[idx], zero, got[idx], check=False) - ne.inverse_dynamics(q[idx], zero, zero, check=False)
    bound = K * EPS * mech.dof * (np.abs(tau[idx]).max() + np.abs(mq).max() + np.abs(h).max())
    benchmark.extra_info.update(
        backward_error=float(np.abs(residual).max()),
        bound=float(bound),
        forward_rel_err=float(np.abs(got[idx] - qdd[idx]).max() / np.abs(qdd[idx]).max()),
        maxrss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    )
    assert np.isfinite(got).all(), f"{method}: NaN/Inf in the accelerations"
    assert np.abs(residual).max() <= bound, (
        f"{method} on {mech.name}: backward error {np.abs(residual).max():.3e} > bound {bound:.3e}"
    )


_MEMORY_PROBE = """
import json, resource, sys
import numpy as np
from exo_bench import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain
n, samples = int(sys.argv[1]), int(sys.argv[2])
mech = chain(n, 3)
q, qd, qdd = random_states(mech, samples, seed=n)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
model = prepare(mech, "newton-euler")
tau = model.inverse_dynamics(q, qd, qdd)
back = model.forward_dynamics(q, qd, tau)
print(json.dumps({"peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "before_model_mb": before / 1024, "finite": bool(np.isfinite(back).all())}))
"""


def _memory_cases(sw):
    return [(n, 3, "chain") for n in (sw.newton_euler_n or (200,))]


def test_newton_euler_memory(benchmark, sweep, n, dim, topology):
    """The whole process's peak resident set (``ru_maxrss``: Python, numpy, numba and its compiled
    kernels, the states, the model) when newton-euler runs inverse and then forward dynamics, with
    validation, on a 3D chain of n links in a fresh process (n = 10,000 in the full profile: the
    goal is under 1 GB). ``n`` of the quick profile: 200."""
    import json
    import subprocess
    import sys

    benchmark.group = "memory-newton-euler"
    samples = int(max(1, min(SAMPLES[sweep.name], sweep.array_bytes // (4 * 8 * 3 * n))))
    r = subprocess.run(
        [sys.executable, "-c", _MEMORY_PROBE, str(n), str(samples)], capture_output=True, text=True, timeout=1800
    )
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["finite"]
    benchmark.extra_info.update(
        method="newton-euler (numba)",
        n=n,
        dim=dim,
        topology=topology,
        mechanism=f"chain{n}-{dim}d",
        samples=samples,
        batched=True,
        **got,
    )
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)
