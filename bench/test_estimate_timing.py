"""The cost model (exo_bench/api/cost_model.py) against measurement, a benchmark: within 2x of the peak
memory and the wall time of preparing a method and running a batch, across n, for the methods whose
cost grows fastest with n (the recurrence's increment tables, n^3; Pinocchio's Data, nv^3).

A timing goal, so it lives here and not in tests/ (issue 34, F2: on a loaded machine it measured
198 MB against an estimated 411 MB and failed the README's test command). In the default run
(``--benchmark-disable``, pyproject's addopts) it is skipped with the reason; run it with
``pytest bench/test_estimate_timing.py --benchmark-enable`` on a machine that runs it alone. The
deterministic part (the memory estimate against counted allocations) is in
tests/test_estimate_vs_measured.py.

Each point runs in a fresh process: numba's machine code is loaded (from its disk cache, or
compiled) before the measurement starts, so its one-time :data:`~exo_bench.models.runtime.prepared.NUMBA_BYTES`
are left out of the estimate compared; the states are generated after the memory baseline (they
count in the estimate's arrays) and before the clock starts (their generation is not the method's
work). Memory is the growth of the peak resident set (``VmHWM`` after a reset through
/proc/self/clear_refs, as ``bench.calibration.measure`` does: Pinocchio allocates in C++ where
tracemalloc does not see).

Error model: memory estimates are upper bounds rounded up (measured/estimated 0.6 to 0.95 when
fitted), held within [0.5, 2] as they are. Times are the quiet reference machine's (the shared 2-core
machine) times :data:`~exo_bench.api.cost_formulas.LOADED` = 2, its speed with a second job, and a
host's times vary 2-5x with its load, so the time of each point is held within 2x of the estimate once
divided by this host's speed factor (the geometric mean of the points' measured/estimated times, which
must lie within [0.2, 5]; 0.37-0.45 on the quiet reference machine, 2026-11-24): the goal holds the shape of
the model across n and methods, and its scale within 5x. Each point's time is the fastest of
:data:`PROCESSES` rounds of fresh processes, and points outside are measured once more before it fails;
the failure names them (recalibrate with ``python -m exo_bench.bench.perf.calibration``). A load
that holds both cores for the whole run is outside this model: it slows the parallel
matrix-factored batch about 3x and the serial methods 1.0-1.6x (measured under a two-thread numpy
product).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import pytest

from exo_bench.api import METHODS
from exo_bench.models.runtime.prepared import NUMBA_BYTES
from exo_bench.api.cost_model import estimate
from exo_bench.models.mechanism.presets import chain

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="VmHWM and clear_refs are Linux's")

CHILD = r"""
import gc, json, sys, time
method, dim, samples, ns = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), [int(x) for x in sys.argv[4:]]
from exo_bench.api import method_class, prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain
method_class(method)                                   # the method's imports, outside
# numba's machine code, outside, for every method: the compiled kernel the batch takes (serial or
# parallel) and the compiled validation pass that every method's checked call runs (pinocchio too: left
# in, its first point measured 1.9 s and 259 MB against 0.13 s and 147 MB estimated, the load of numba)
warm = prepare(chain(2, dim), method)
warm.inverse_dynamics(*random_states(chain(2, dim), max(2, min(samples, 5000)), 0))

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024

out = []
for n in ns:                                           # one process, one point after the other
    gc.collect()
    open("/proc/self/clear_refs", "w").write("5")      # reset the peak (VmHWM)
    r0 = status("VmRSS")
    mech = chain(n, dim)
    q, qd, qdd = random_states(mech, samples, 0)
    t0 = time.perf_counter()
    tau = prepare(mech, method).inverse_dynamics(q, qd, qdd)
    out.append({"n": n, "bytes": status("VmHWM") - r0, "seconds": time.perf_counter() - t0})
    del q, qd, qdd, tau
print(json.dumps(out))
"""

#: method, dim, samples -> the n measured (in one process): the n^3 terms (recurrence's tables,
#: Pinocchio's Data) or the batch's arrays (matrix-factored) dominate: 100-650 MB, 0.3-3 s each on
#: the reference machine. ``matrix`` is left out: with its compiled kernel its peak grows by 2-6 MB
#: (below BASE_BYTES, where the estimate is a floor), and compiling its kernels would cost CI 10 s.
POINTS = {("recurrence", 2, 1): (280, 340), ("pinocchio", 3, 1): (50, 70), ("matrix-factored", 3, 40000): (30, 50)}
#: Rounds of fresh processes, one per method in each round: each point's time is the fastest of them,
#: its memory the largest (a burst of load, or a slow spell of the shared machine, slows one round and
#: not all of them; a second run in one process would reuse the first's memory and leave its first
#: touch out).
PROCESSES = 3


def _measure(method, dim, samples, ns) -> list[dict]:
    r = subprocess.run(
        [sys.executable, "-c", CHILD, method, str(dim), str(samples), *map(str, ns)],
        capture_output=True,
        text=True,
        timeout=1800,  # a safety net: the points take seconds
    )
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def _points() -> list[tuple]:
    """Every point: (key, n, memory ratio, time ratio, measured, estimate); ratios measured / estimated."""
    out = []
    rounds = [{key: _measure(*key, ns) for key, ns in POINTS.items()} for _ in range(PROCESSES)]  # interleaved
    for key in POINTS:
        method, dim, samples = key
        for by_n in zip(*(r[key] for r in rounds)):
            got = {
                "n": by_n[0]["n"],
                "bytes": max(g["bytes"] for g in by_n),
                "seconds": min(g["seconds"] for g in by_n),
            }
            est = estimate(chain(got["n"], dim), method, samples)
            memory = est.memory - (NUMBA_BYTES if METHODS[method].compiled else 0)  # loaded before the measurement
            out.append((key, got["n"], got["bytes"] / memory, got["seconds"] / est.seconds, got, est))
    return out


def _outside(points) -> list[str]:
    """The points outside the bands, in words: memory within 2x; time within 2x once divided by this
    host's speed against the reference machine (the geometric mean of the time ratios, itself
    within 5x)."""
    speed = math.exp(sum(math.log(p[3]) for p in points) / len(points))
    bad = [
        f"{k[0]} {k[1]}D n={n}: measured {g['bytes'] / 1e6:.0f} MB and {g['seconds']:.2f} s, estimated "
        f"{e.memory / 1e6:.0f} MB and {e.seconds:.2f} s (host speed factor {speed:.2f})"
        for k, n, mem, sec, g, e in points
        if not (0.5 <= mem <= 2 and 0.5 <= sec / speed <= 2)
    ]
    if not 0.2 <= speed <= 5:
        bad.append(f"this host runs the methods {speed:.2f}x the reference machine's times")
    return bad


def test_the_estimate_is_within_2x_of_the_measured_memory_and_time(benchmark):
    """A timing goal, run with ``--benchmark-enable`` only: the cost model's memory and time are within
    2x of a fresh process's measured peak resident set and wall time (see the module docstring)."""
    if benchmark.disabled:
        pytest.skip("a timing goal (wall time and resident memory of this machine): run with --benchmark-enable")
    benchmark.group = "estimate-vs-measured"
    bad = _outside(_points())
    if bad:  # a noisy neighbour: once more
        bad = _outside(_points())
    benchmark.extra_info["outside"] = bad
    assert not bad, "; ".join(bad)
