"""What the benchmark suite measures, in a quick profile (CI, the main job) and a full one, and which rows
of bench/test_compose.py run (:func:`predicted_skip`: by a predicted cost, never by a clock).

Set with ``pytest bench --sweep=full`` (``exo-bench bench --full`` passes it on).
PyDy's Cython generator composes and compiles C for each mechanism (about 7 s at n = 5 in 3D, 21 s
at n = 20 in 2D, minutes at n = 20 in 3D): it runs on the chains of ``pydy_n`` and on exo5-3d.
"""

from __future__ import annotations

from dataclasses import dataclass

from exo_bench.api.cost_formulas import _loglog


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


# Which rows of bench/test_compose.py run: decided by a predicted cost, never by a clock.

#: ``(method, dim) -> ((n, seconds), ...)``: one composition of a chain of n links, measured.
COMPOSE_POINTS: dict[tuple[str, int], tuple[tuple[int, float], ...]] = {
    ("lagrange", 2): ((1, 0.00415), (2, 0.0192), (3, 0.0604), (4, 0.145), (5, 0.29), (6, 0.543)),
    ("lagrange-expr", 2): ((1, 0.126), (2, 0.521), (3, 1.36), (4, 2.75), (5, 4.97), (6, 8.38)),
    ("sympy-lagrangesmethod", 2): ((1, 0.0756), (2, 1.09), (3, 4.18), (4, 10.9), (5, 23.7), (6, 45.9)),
    ("sympy-kanesmethod", 2): ((1, 0.0492), (2, 0.172), (3, 0.421), (4, 0.87), (5, 1.59), (6, 2.64)),
    ("matrix", 2): ((1, 0.000496), (2, 0.0023), (3, 0.0051), (4, 0.00848), (5, 0.0125), (6, 0.0181)),
    ("recurrence", 2): ((1, 0.000523), (2, 0.00244), (3, 0.00535), (4, 0.00941), (5, 0.016), (6, 0.0215)),
    ("lagrange", 3): ((1, 0.00766), (2, 0.0606), (3, 0.234), (4, 0.592), (5, 1.37)),
    ("lagrange-expr", 3): ((1, 0.393), (2, 1.81), (3, 4.91), (4, 10.2), (5, 19.5)),
    ("sympy-lagrangesmethod", 3): ((1, 0.137), (2, 5.3), (3, 23.6), (4, 67.2), (5, 153.0)),
    ("sympy-kanesmethod", 3): ((1, 0.0837), (2, 0.387), (3, 1.16), (4, 2.62), (5, 4.96)),
    ("matrix", 3): (
        (1, 0.000977),
        (2, 0.00456),
        (3, 0.01),
        (4, 0.0179),
        (5, 0.0278),
        (10, 0.135),
        (20, 0.639),
        (50, 5.37),
    ),
    ("recurrence", 3): (
        (1, 0.00113),
        (2, 0.00509),
        (3, 0.0193),
        (4, 0.0267),
        (5, 0.0313),
        (10, 0.159),
        (20, 0.898),
        (50, 10.3),
    ),
}

#: A row predicted within the budget runs with this many times the budget as its limit.
LOAD_ALLOWANCE = 10.0


def predicted_seconds(method: str, n: int, dim: int) -> float:
    """Predicted seconds of composing an ``n``-link model in ``dim`` D with ``method`` (module docstring)."""
    points = COMPOSE_POINTS.get((method, dim))
    if points is None:
        known = sorted({m for m, _ in COMPOSE_POINTS})
        raise ValueError(f"compose cost: field 'method': expected one of {known} in 2D or 3D, got {method!r} in {dim}D")
    return _loglog([(float(k), s) for k, s in points], float(n))


def predicted_skip(method: str, n: int, dim: int, budget: float) -> str | None:
    """Why the row is skipped before any work (its prediction over ``budget`` seconds), or None."""
    predicted = predicted_seconds(method, n, dim)
    if predicted <= budget:
        return None
    return (
        f"composing n={n}, dim={dim} is predicted to take {predicted:.3g} s (bench/perf/profiles.py), "
        f"over the profile's compose budget of {budget:g} s"
    )
