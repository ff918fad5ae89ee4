"""The cost formulas of each method: setup memory and time, seconds per call and per sample, and
the note naming what dominates (the figures and how they were measured: :mod:`exo_bench.api.cost_model`).
Each :class:`~exo_bench.api.methods.MethodSpec` names its :class:`CostModel`; the bytes of one
sample's temporaries belong to the prepared-model class (``sample_bytes``), which sizes its chunks
from them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable

from exo_bench.models.runtime.prepared import Kernel
from exo_bench.models.mechanism.mechanism import Mechanism


F8 = 8  # bytes per float64

#: Memory of the interpreter's own work around a run (imports are already counted in the baseline).
BASE_BYTES = 16 * 2**20


#: The load of the reference machine (the shared 2-core machine of CI and the sweeps): the recalibrated
#: times below (``recurrence``, ``pinocchio``, ``matrix-factored``: 2026-11-24) are the quiet machine's
#: fastest of repeated runs times this, the speed with a second job on its two cores (the older figures of
#: the other methods were measured with other jobs running).
LOADED = 2.0
#: Bytes per second at which a large batch streams its arrays (``q, qd, qdd`` read, ``tau`` written
#: and first touched): the per-sample time of a batch is at least its arrays' bytes over this (times
#: :data:`LOADED`). Quiet, 2026-11-24, matrix-factored 3D, 40,000 samples (192 MB of arrays at n = 50):
#: the first batch of a fresh process takes 0.065-0.076 s or 0.112-0.124 s at n = 50 (two modes, each
#: in about half of the processes, clustered in time; 0.037 s at n = 30), and a warm process 1.4-1.5 us
#: per sample at n = 50 (0.44 and 0.86 us in batches of 2000, which stay in cache): the slower mode,
#: 1.65 GB/s over the four arrays.
ARRAY_BANDWIDTH = 1.65e9


# ------------------------------------------------------------------------------ per-method models
@dataclass(frozen=True)
class CostModel:
    """Formulas in ``(n, dim)``: one-time setup (bytes, seconds), per-sample seconds, and a note on
    what dominates (the per-sample bytes are the prepared-model class's ``sample_bytes``). What a
    kernel adds (its speed against these figures, its compile time, its runtime's memory) is the
    kernel object's (:class:`~exo_bench.models.runtime.prepared.Kernel`, :func:`kernel_note`)."""

    setup_bytes: Callable[[Mechanism, dict], float]
    setup_seconds: Callable[[Mechanism, dict], float]
    sample_seconds: Callable[[int, int], float]
    note: Callable[[Mechanism, dict], str] = lambda m, o: ""
    call_seconds: float = 1e-4  # per call (chunk): Python and numpy overhead


def _size(x: float) -> str:
    if x >= 1e9:
        return f"{x / 1e9:.1f} GB"
    if x >= 1e6:
        return f"{x / 1e6:.0f} MB"
    return f"{x / 1e3:.0f} kB"


def _seconds(x: float) -> str:
    if x >= 3600:
        return f"{x / 3600:.1f} h"
    if x >= 1:
        return f"{x:.0f} s" if x >= 10 else f"{x:.1f} s"
    return f"{x * 1e3:.0f} ms" if x >= 1e-3 else f"{x * 1e6:.0f} us"


def _pin_data(mech: Mechanism, options: dict) -> tuple[int, int]:
    from exo_bench.models.engines.urdf import pinocchio_data_bytes

    threads = int(options.get("threads", 1) or 1)
    count = 1 + (threads + 1 if threads > 1 else 0)  # this thread's Data, the pool's and its construction's copy
    return pinocchio_data_bytes(mech), count


def _pin_setup_bytes(mech, options):
    one, count = _pin_data(mech, options)
    return one * count + 120_000 * mech.nlinks + 2 * 2**20  # the model: <= 90 kB per link (3D n = 100: 9 MB)


def _pin_setup_seconds(mech, options):
    one, count = _pin_data(mech, options)
    # pin.Data(model) zero-fills its pages and the first call touches them again: 2.2 GB/s with the
    # page faults on the quiet machine, and 0.2 ms per link for the model. Measured in fresh processes
    # (prepare and the first call, the fastest of four): 3D n = 30, 50, 70, 90 (30, 122, 319, 665 MB):
    # 0.020, 0.061, 0.151, 0.305 s (bench/test_estimate_timing.py holds these within 2x).
    return LOADED * (one * count / 2.2e9 + 2e-4 * mech.nlinks)


def _pin_note(mech, options):
    from exo_bench.models.engines.urdf import pinocchio_model_size

    nv, _ = pinocchio_model_size(mech)
    one, count = _pin_data(mech, options)
    many = "" if count == 1 else f" x {count}"
    return f"a pin.Data holds four nv^3 tensors: {_size(one)} at nv = {nv}{many}, docs/pinocchio-memory.md"


def _matrix_setup(mech, options):
    return F8 * 8 * mech.nlinks**2 + 2**20  # coupling and gravity coefficients, several n x n


def kernel_note(kernels: tuple[Kernel, ...]) -> str:
    """What the note of an estimate adds for the kernels an option runs: their compile time where
    they are compiled (paid once per machine, and per edit of a kernel's source, so named here and not
    added to the seconds: the run's time does not depend on the state of the cache), else their option."""
    compile_s = [k.compile_seconds for k in kernels if k.compile_seconds is not None]
    if compile_s:
        return (
            f"; compiled kernel ({kernels[0].option}): the first use on a machine compiles it in up to "
            f"{max(compile_s):g} s (then cached on disk)"
        )
    return f"; {kernels[0].option} kernel" if kernels else ""


#: Lagrange's derivation, measured on chains: (n, dim) -> (seconds, peak bytes) (module docstring).
LAGRANGE_POINTS: dict[tuple[int, int], tuple[float, float]] = {
    (1, 2): (0.19, 9.1e6),
    (2, 2): (0.14, 10.2e6),
    (3, 2): (0.24, 11.8e6),
    (4, 2): (0.42, 14.1e6),
    (5, 2): (0.87, 17.5e6),
    (6, 2): (1.14, 23.0e6),
    (8, 2): (3.38, 39.7e6),
    (10, 2): (4.15, 69.9e6),
    (15, 2): (15.9, 245.7e6),
    (20, 2): (42.6, 673.8e6),
    (30, 2): (174.7, 3066.1e6),
    (1, 3): (0.14, 9.4e6),
    (2, 3): (0.28, 12.4e6),
    (3, 3): (0.57, 16.9e6),
    (4, 3): (1.57, 25.0e6),
    (5, 3): (2.79, 37.1e6),
    (6, 3): (3.56, 55.7e6),
    (8, 3): (8.37, 122.2e6),
    (10, 3): (17.4, 241.9e6),
}


def _loglog(points: list[tuple[float, float]], x: float) -> float:
    """Interpolate ``points`` (sorted by x) linearly in log-log; beyond the last point, extend the
    power law through the last two points (the steepest measured growth)."""
    if x <= points[0][0]:
        return points[0][1]
    for (x0, y0), (x1, y1) in zip(points, points[1:]):
        if x <= x1 or (x1, y1) == points[-1]:
            p = math.log(y1 / y0) / math.log(x1 / x0)
            return y0 * (x / x0) ** p
    return points[-1][1]


def _lagrange(mech: Mechanism, k: int) -> float:
    pts = sorted((float(n), v[k]) for (n, d), v in LAGRANGE_POINTS.items() if d == mech.dim)
    return _loglog(pts, float(mech.nlinks))


def recurrence_table_floats(mech: Mechanism) -> int:
    """Floats of the recurrence's increment tables (``exo_bench.matrix_method.numba_kernels.recurrence.tables``):
    per link k an ``m x m`` block and ``m`` more, m = its ancestors and itself; sum m^2 is n^3 / 3
    for a chain (3.3e8 floats at n = 1000)."""
    depth = [0] * mech.nlinks
    for k, p in enumerate(mech.parent):
        depth[k] = 1 + (depth[p] if p >= 0 else 0)
    return sum(m * m + m for m in depth)


#: Copies of the tables alive at the peak of building them: one (they are written link by link into
#: one array, numba_kernels.recurrence.tables), rounded up for the block being written and the
#: allocator (measured growth of the peak resident set: 3.00 GB at 2D n = 1000, where one copy is
#: 2.67 GB; before, the blocks, their flattened copies, the concatenation and its float64 copy made
#: 10.6 GB there).
RECURRENCE_TABLE_COPIES = 1.1
#: Seconds per table float to build the tables (numpy per link). Quiet, 2026-11-24: 0.8e-8 to 1.6e-8 at
#: 2D n = 280, 2.3e-8 at 500, 2.0e-8 at 1000 (6.6 s for 3.3e8 floats; 12.7 s under a second job): 1.5e-8
#: times :data:`LOADED`.
RECURRENCE_TABLE_SECONDS = LOADED * 1.5e-8


def _recurrence_setup_bytes(mech, options):
    return _matrix_setup(mech, options) + int(RECURRENCE_TABLE_COPIES * F8 * recurrence_table_floats(mech))


def _recurrence_setup_seconds(mech, options):
    return 0.01 + RECURRENCE_TABLE_SECONDS * recurrence_table_floats(mech)


# The kernels' compile times, speeds and runtime memory: matrix_method/kernels.py, models/newton_euler/kernels.py.
PINOCCHIO = CostModel(
    _pin_setup_bytes,
    _pin_setup_seconds,
    # per sample, warm, batches of 500 (quiet): 2D n = 5, 25, 100: 3.2, 13.2, 51.2 us; 3D: 5.2, 22.9, 95.7 us
    sample_seconds=lambda n, d: LOADED * ((0.7 + 0.5 * n) if d == 2 else (0.5 + 0.95 * n)) * 1e-6,
    note=_pin_note,
)
LAGRANGE = CostModel(
    lambda m, o: _lagrange(m, 1),
    lambda m, o: _lagrange(m, 0),
    sample_seconds=lambda n, d: (0.5 + 0.05 * d * n * n) * 1e-6,
    note=lambda m, o: "the sympy derivation",
)
MATRIX = CostModel(
    _matrix_setup,
    lambda m, o: 0.01 + 5e-6 * m.nlinks**2,
    sample_seconds=lambda n, d: (1.0 + (0.1 if d == 2 else 0.3) * n * n) * 1e-6,
    note=lambda m, o: f"every n x n matrix of eq. (5)/(17) per sample (n = {m.nlinks})",
)
MATRIX_PAPER = CostModel(
    _matrix_setup,
    lambda m, o: 0.01 + 5e-6 * m.nlinks**2,
    sample_seconds=lambda n, d: (1.0 + (0.1 if d == 2 else 0.3) * n * n) * 1e-6,
    note=lambda m, o: f"every n x n matrix of eq. (17) per sample (n = {m.nlinks})",
)
RECURRENCE = CostModel(
    _recurrence_setup_bytes,
    _recurrence_setup_seconds,
    # per sample, warm (quiet): 2D n = 5, 25, 100, 200: 1.58, 51.7, 1890, 14600 us (1000: 2.8 s);
    # 3D: 2.39, 80.5, 3180, 25000 us
    sample_seconds=lambda n, d: (
        LOADED * ((1.0 + 0.03 * n**2 + 0.0018 * n**3) if d == 2 else (1.5 + 0.05 * n**2 + 0.003 * n**3)) * 1e-6
    ),
    note=lambda m, o: f"the matrices grown link by link, n x n per sample (n = {m.nlinks})",
)
MATRIX_FACTORED = CostModel(
    _matrix_setup,
    # prepare, warm (quiet): 3D n = 10, 50, 100, 200: 0.4, 2.6, 4.9, 17 ms
    lambda m, o: LOADED * (0.001 + 4e-7 * m.nlinks**2),
    # per sample, warm, batches of 2000 (quiet): 2D n = 5, 25, 100, 200: 0.070, 0.36, 2.28, 5.75 us;
    # 3D: 0.090, 0.39, 2.99, 8.82 us (the SIMD kernels of issue 23; n = 1000 3D: 197 us in the full sweep)
    sample_seconds=lambda n, d: (
        LOADED * ((0.04 + 0.013 * n + 1.0e-4 * n**2) if d == 2 else (0.05 + 0.016 * n + 1.4e-4 * n**2)) * 1e-6
    ),
    note=lambda m, o: f"O(n) per sample, no matrix formed (n = {m.nlinks})",
)
# The peers (extra [peers]): a Python loop over samples into MuJoCo / Drake. Peak RSS growth of
# prepare + one call on 3D chains of 10 and 100 links: MuJoCo 12 / 33 MB, Drake 16 / 50 MB; per
# sample on the shared 2-core machine (noisy, rounded up): MuJoCo 27-70 us at n = 5, ~1.1 ms at
# n = 100; Drake 40-170 us at n = 5, 2-4 ms at n = 100.
MUJOCO = CostModel(
    lambda m, o: 16 * 2**20 + 300_000 * m.nlinks,
    lambda m, o: 0.6 + 5e-3 * m.nlinks,
    sample_seconds=lambda n, d: (20.0 + 12.0 * n) * 1e-6,
    note=lambda m, o: "a Python loop over mj_rne, one MjData",
)
DRAKE = CostModel(
    lambda m, o: 20 * 2**20 + 450_000 * m.nlinks,
    lambda m, o: 0.8 + 2e-3 * m.nlinks,
    sample_seconds=lambda n, d: (40.0 + (20.0 if d == 2 else 40.0) * n) * 1e-6,
    note=lambda m, o: "a Python loop over CalcInverseDynamics, one Context",
)
# newton-euler keeps O(n) numbers (an (8, n) table) and O(n) scratch per sample (its sample_bytes). Per
# sample (quiet, batches of 2000, check=True, 2026-11-24): numpy kernel 2D n = 5, 100, 300: 0.77, 15.4,
# 50.1 us; 3D: 0.83, 21.6, 73.2 us; the compiled kernel 0.07-0.13 of those (3D n = 100, 1000: 1.46,
# 26.8 us): the kernels' speed (models/newton_euler/kernels.py).
NEWTON_EULER = CostModel(
    lambda m, o: F8 * 16 * m.nlinks + 2**20,
    lambda m, o: 0.01 + 2e-6 * m.nlinks,
    sample_seconds=lambda n, d: LOADED * (0.2 + 0.08 * d * n) * 1e-6,
    note=lambda m, o: f"O(n) per sample, two passes over the tree (n = {m.nlinks})",
)
