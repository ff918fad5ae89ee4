"""Which rows of bench/test_compose.py run: decided by a predicted cost, never by a clock.

A row composes one model's equations symbolically with one method. Whether it runs is decided
before the work, from the row's counted size (the method, the number of links ``n`` and the
dimension) through :data:`COMPOSE_POINTS`: the seconds each method took to compose chains on the
reference machine (reports/full/benchmarks-full.json of 2026-11-24, commit 6947545, 2-core AMD
EPYC; branched models of one n took the same within 10 %). Between points the prediction is
interpolated in log-log, beyond the largest n extended by the power law through the last two
points (the cost model's rule, :func:`exo_bench.api.cost_formulas._loglog`), so it grows with n.

A row predicted over the profile's ``compose_budget`` is skipped with a reason naming the
prediction (the same rows on every machine, under any load); a row predicted within it runs with
:data:`LOAD_ALLOWANCE` times the budget as its time limit, so that a loaded machine finishes it
rather than turning it into a skip. Running out of that limit means the prediction was wrong by
more than the allowance: the row then fails, naming both.
"""

from __future__ import annotations

from exo_bench.api.cost_formulas import _loglog

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
        f"composing n={n}, dim={dim} is predicted to take {predicted:.3g} s (bench/perf/compose_cost.py), "
        f"over the profile's compose budget of {budget:g} s"
    )
