"""The batched path when the user's code started numba's threads first (issue 23, the threading trap).

If a user's code runs a ``prange`` function before exo-bench loads, numba keeps the threading layer
it picked then (OpenMP where libgomp is loaded), and exo-bench can no longer choose ``workqueue``.
``matrix-factored (numba)``'s batched path never enters numba's threading layer: it splits a large
batch over a pool of Python threads that call the serial SIMD kernel (matrix_method/numba_kernels/simd.py).
This test runs, in a fresh process, an OpenMP ``prange`` function first, then exo-bench, and checks
that numba kept OpenMP (the premise), that the batch path gives the numpy reference's forces
(error model of tests/test_compiled.py) at sizes below and above the threshold of the thread split,
and that no exo-bench kernel was a ``parallel=True`` dispatcher. The timing (within 1.2x of the
normal speed) is a benchmark row, never a test: bench/test_simd.py.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from exo_bench.bench.perf.reports.simd_goals import OMP_FIRST

_PROBE = (
    OMP_FIRST
    + r"""
layer_before = numba.threading_layer()
import json
from exo_bench import prepare, presets
from exo_bench.matrix_method.numba_kernels import common as compiled, simd as compiled_simd
from exo_bench.models.machine import numba_runtime
mech = presets.exo5(dim=3)
fast, ref = prepare(mech, "matrix-factored"), prepare(mech, "matrix-factored", kernel="numpy")
rng = np.random.default_rng(0)
worst = 0.0
for S in (compiled_simd.LANES + 1, numba_runtime.PARALLEL_MIN_SAMPLES, 10_000):
    q = rng.uniform(-3, 3, (S, mech.dof)); q[:, -5:] = rng.uniform(0.2, 1.2, (S, 5))
    qd, qdd = rng.normal(size=q.shape), rng.normal(size=q.shape)
    want = ref.inverse_dynamics(q, qd, qdd)
    got = fast.inverse_dynamics(q, qd, qdd, check=False)
    worst = max(worst, float(np.abs(got - want).max() / np.abs(want).max()))
print(json.dumps({"layer_before": layer_before, "layer_after": numba.threading_layer(),
                  "threads": numba.get_num_threads(), "worst": worst,
                  "batch_kernel_parallel": bool(fast.batch_kernel.targetoptions.get("parallel"))}))
"""
)


def test_batch_path_with_numbas_openmp_threads_started_first():
    r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True, timeout=600)
    if r.returncode != 0 and "omp" in r.stderr.lower() and "threading layer" in r.stderr.lower():
        pytest.skip(f"numba's OpenMP layer is not available here: {r.stderr.strip().splitlines()[-1]}")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["layer_before"] == "omp" and out["layer_after"] == "omp", out  # the premise: the user's layer
    assert not out["batch_kernel_parallel"], out  # ours never enters it
    assert out["worst"] <= 1e-14, out
