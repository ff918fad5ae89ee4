"""What the benchmark suite measures, in a quick profile (CI, the main job) and a full one.

Set with ``pytest bench --sweep=full`` (``exo-bench bench --full`` passes it on).
PyDy's Cython generator composes and compiles C for each mechanism (about 7 s at n = 5 in 3D, 21 s
at n = 20 in 2D, minutes at n = 20 in 3D): it runs on the chains of ``pydy_n`` and on exo5-3d.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Sweep:
    name: str
    compose_2d: tuple[int, ...]  # n for composing the equations, 2D
    compose_3d: tuple[int, ...]  # n for composing the equations, 3D
    compose_budget: float  # seconds per derivation before a row is skipped
    derive_budget: float  # seconds for lagrange's derivation before a numeric row is skipped
    inverse_n: tuple[int, ...]  # n for numeric inverse dynamics, batched
    per_call_n: tuple[int, ...]  # n for numeric inverse dynamics, one sample per call
    pydy_n: tuple[int, ...]  # n of the chains PyDy's Cython generator compiles (exo5-3d always)
    samples: int  # samples per batched call
    inverse_budget: float  # projected seconds per batched call before a row is skipped
    error_subsample: int  # samples checked against the 50-digit reference
    compose_3d_fast: tuple[int, ...] = ()  # more n for composing in 3D, matrix and recurrence only
    row_budget: float = 1800.0  # seconds for one row of the distributed sweep (bench/perf/rows.py) before it is killed
    scaling_n: tuple[int, ...] = ()  # more n for batched inverse dynamics, 3D chains, every method within its budget
    newton_euler_n: tuple[int, ...] = ()  # more n, 3D chains, newton-euler alone (inverse and forward)
    forward_n: tuple[int, ...] = (
        5,
        20,
    )  # n for forward dynamics per sample, 3D chains (bench/test_forward_dynamics.py)
    array_bytes: int = 2**27  # a batched row's samples are capped so its q, qd, qdd, tau take at most this


QUICK = Sweep(
    "quick",
    compose_2d=(1, 2, 3),
    compose_3d=(1, 2),
    compose_budget=20.0,
    derive_budget=10.0,
    inverse_n=(1, 2, 5, 20),
    per_call_n=(2, 5, 20),
    pydy_n=(2,),
    samples=1000,
    inverse_budget=5.0,
    error_subsample=4,
)
FULL = Sweep(
    "full",
    compose_2d=(1, 2, 3, 4, 5, 6),
    compose_3d=(1, 2, 3, 4, 5),
    compose_budget=300.0,
    derive_budget=120.0,
    inverse_n=(1, 2, 3, 5, 10, 20, 50, 100),
    per_call_n=(2, 5, 20),
    pydy_n=(2, 5),
    samples=10_000,
    inverse_budget=120.0,
    error_subsample=8,
    compose_3d_fast=(10, 20, 50),
    row_budget=1800.0,
    scaling_n=(200, 500, 1000),
    newton_euler_n=(10_000,),
    forward_n=(5, 20, 50, 100, 200, 500, 1000),
)
SWEEPS = {"quick": QUICK, "full": FULL}


def current(option: str | None = None) -> Sweep:
    name = option or "quick"
    if name not in SWEEPS:
        raise ValueError(f"sweep: expected one of {', '.join(SWEEPS)}, got {name!r}")
    return SWEEPS[name]
