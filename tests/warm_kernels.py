"""Compile the numba kernels the suite runs into numba's cache, once, before the workers start.

Run by the controller of the README's test command (:func:`xdist_workers.pytest_sessionstart`) as
``python tests/warm_kernels.py PART`` with ``NUMBA_CACHE_DIR`` the workers' shared cache, one process
per part, the parts at once. Without it the first tests of both workers, and every CLI process a test
starts before the kernel it runs is saved, compile the same kernels again: each process that misses
the cache compiles, and numba's index lock (models/machine/numba_cache.py) serialises only the saving.
With a warm cache this only loads (numba checks every index's source stamp, so a changed kernel is
compiled here, once).

The parts split the compile work of a fresh clone in two of about equal size (measured CPU seconds in
each part's last output line): ``matrix`` (the matrix methods' and the recurrence's kernels) and
``newton-euler`` (its kernels and the analytic derivatives'). Each calls every public call of each
method on exo5 in 2D and 3D, one sample and a batch, checked and unchecked: the signatures the tests
use (a kernel missed here is compiled by the test that needs it, as before: correctness never
depends on this warm-up).
"""

from __future__ import annotations

import resource
import sys

import numpy as np

PARTS = {
    "matrix": ("matrix", "matrix-factored", "matrix-paper", "recurrence"),
    "newton-euler": ("newton-euler",),
}
#: Samples of a batch: at least two SIMD blocks of 32 lanes and a tail.
BATCH = 70


def states(dof: int, samples: int | None) -> np.ndarray:
    if samples is None:
        return np.linspace(0.1, 0.9, dof)
    return np.linspace(0.1, 0.9, samples * dof).reshape(samples, dof)


def warm(method: str, dim: int) -> None:
    from exo_bench import prepare, presets
    from exo_bench.models.derivatives import Derivatives

    model = prepare(presets.exo5(dim=dim), method)
    for samples in (None, BATCH):
        q = states(model.dof, samples)
        for check in (True, False):
            model.inverse_dynamics(q, q, q, check=check)
            model.mass_matrix(q, check=check)
            model.bias_forces(q, q, check=check)
            model.forward_dynamics(q, q, q, check=check)
    if method == "newton-euler":
        d = model.derivatives
        for samples in (None, BATCH):
            Derivatives(model.mechanism, products="numba").inverse_dynamics_vjp(*[states(model.dof, samples)] * 4)
            q = states(model.dof, samples)
            d.inverse_dynamics(q, q, q)
            d.forward_dynamics(q, q, q)
            d.inverse_dynamics_jvp(q, q, q, q, q, q)
            d.inverse_dynamics_vjp(q, q, q, q)
            d.forward_dynamics_jvp(q, q, q, q, q, q)
            d.forward_dynamics_vjp(q, q, q, q)


def main(part: str) -> int:
    for method in PARTS[part]:
        for dim in (2, 3):
            warm(method, dim)
    cpu = resource.getrusage(resource.RUSAGE_SELF)
    print(f"warm_kernels {part}: {cpu.ru_utime + cpu.ru_stime:.1f} s CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
