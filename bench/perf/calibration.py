"""Calibration of the cost model of :mod:`exo_bench.api.cost_model`: measure memory and time of one method
on one model in a fresh process, and the table of measured against estimated values
(``python -m exo_bench.bench.perf.calibration``). A development tool: nothing else imports it.
"""

from __future__ import annotations

from exo_bench.api.cost_model import BASE_BYTES, estimate
from exo_bench.api.methods import derives_within_budget, preference


# ------------------------------------------------------------------------------ calibration
_MEASURE = r"""
import json, sys, time
from exo_bench.api import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain
import exo_bench.{module}  # imports outside the measurement

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024

def reset_peak():
    open("/proc/self/clear_refs", "w").write("5")

mech = chain({n}, {dim})
q, qd, qdd = random_states(mech, {samples}, 0)
reset_peak(); r0 = status("VmRSS"); t0 = time.perf_counter()
model = prepare(mech, {method!r}, **{options!r})
model.inverse_dynamics(q[:1], qd[:1], qdd[:1])          # first call: Data, caches
setup_s = time.perf_counter() - t0; setup = status("VmHWM") - r0
reset_peak(); r1 = status("VmRSS"); t0 = time.perf_counter()
tau = model.inverse_dynamics(q, qd, qdd)
run_s = time.perf_counter() - t0; run = status("VmHWM") - r1
print(json.dumps(dict(setup_bytes=setup, setup_seconds=setup_s, run_bytes=run, run_seconds=run_s)))
"""


def measure(method: str, n: int, dim: int, samples: int, options: dict | None = None, timeout: float = 600) -> dict:
    """Measure one point in a fresh process (Linux): the peak-RSS growth and seconds of preparing
    (with the first call) and of one batch of ``samples``; see the module docstring."""
    import json
    import subprocess
    import sys

    from exo_bench.api import METHODS

    module = METHODS[method].module.removeprefix("exo_bench.")
    code = _MEASURE.format(module=module, n=n, dim=dim, samples=samples, method=method, options=options or {})
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    if r.returncode != 0:
        raise RuntimeError(r.stderr.strip().splitlines()[-1] if r.stderr.strip() else f"exit {r.returncode}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def calibration_table(points=None) -> str:
    """Measured against estimated, as a Markdown table (``python -m exo_bench.bench.perf.calibration``)."""
    from exo_bench.models.mechanism.presets import chain

    points = points or [
        (m, n, d, s)
        for m in preference() + ("matrix-paper",)
        if not derives_within_budget(m)  # a derivation's seconds are calibrated on their own
        for d in (2, 3)
        for n in (5, 25, 100)
        for s in (1, 2000)
    ]
    rows = [
        "| method | dim | n | samples | measured MB | estimated MB | measured s | estimated s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for m, n, d, s in points:
        got = measure(m, n, d, s)
        est = estimate(chain(n, d), m, s)
        rows.append(
            f"| {m} | {d} | {n} | {s} | {(got['setup_bytes'] + got['run_bytes']) / 1e6:.1f} | "
            f"{(est.memory - BASE_BYTES) / 1e6:.1f} | {got['setup_seconds'] + got['run_seconds']:.3g} | "
            f"{est.seconds:.3g} |"
        )
    return "\n".join(rows)


if __name__ == "__main__":
    print(calibration_table())
