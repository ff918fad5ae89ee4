"""Composing the equations of motion symbolically: the paper's timing table, and more rows.

Every row of one model must produce the same equations; each test checks its method's
equations against the matrix method's at random points before its timing counts. Caches
(sympy's, the derivation's, the composition's) are cleared before every round, so each round
composes from scratch, as the paper's Mathematica timings did.
"""

from __future__ import annotations

import random

import pytest
import sympy as sp

from exo_bench.bench.perf.profiles import LOAD_ALLOWANCE, predicted_seconds, predicted_skip
from exo_bench.bench.perf.rows import OVER_BUDGET
from exo_bench.bench.perf.profiles import current
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.presets import chain

COMPOSERS = ("lagrange", "lagrange-expr", "sympy-lagrangesmethod", "sympy-kanesmethod", "matrix", "recurrence")
_REFERENCE: dict[Mechanism, tuple] = {}
_WARM: set[str] = set()


def model(n: int, dim: int, topology: str) -> Mechanism:
    """A serial chain (Fig. 2a style) or a branched one: the second half reversed after a branch
    point (Fig. 2b for n = 2, Fig. 5 for n = 4)."""
    m = chain(n, dim)
    if topology == "branched":
        m = m.replace(sign=tuple(1 if i < (n + 1) // 2 else -1 for i in range(n)), name=f"branched{n}-{dim}d")
    return m


def _composer(method: str, budget: float):
    if method in ("lagrange", "lagrange-expr"):
        from exo_bench.lagrange import derive

        engine = "poly" if method == "lagrange" else "expr"
        return lambda m: derive(m, symbolic_parameters=True, budget=budget, engine=engine, cache=False).equations
    if method in ("sympy-lagrangesmethod", "sympy-kanesmethod"):
        from exo_bench.lagrange.peer import peer_equations

        kind = "lagrange" if method == "sympy-lagrangesmethod" else "kane"
        return lambda m: peer_equations(m, kind, symbolic_parameters=True, budget=budget)
    if method == "matrix":
        from exo_bench.matrix_method.symbolic import compose_equations

        return lambda m: compose_equations(m, symbolic_parameters=True)
    from exo_bench.matrix_method.recurrence import compose_equations

    return lambda m: compose_equations(m, symbolic_parameters=True)


def _clear_caches():
    from exo_bench import lagrange
    from exo_bench.matrix_method import symbolic

    sp.core.cache.clear_cache()
    lagrange.clear_cache()
    symbolic.clear_caches()


def _values(eqs) -> dict:
    rng = random.Random(7)
    syms = sorted(set().union(*(e.free_symbols for e in eqs)), key=str)
    return {s: sp.Float(rng.uniform(0.3, 1.3), 30) for s in syms}


def _same_equations(mech: Mechanism, eqs) -> float:
    """Largest relative difference from the matrix method's equations at a random point."""
    if mech not in _REFERENCE:
        from exo_bench.matrix_method.symbolic import compose_equations

        ref = compose_equations(mech, symbolic_parameters=True)
        vals = _values(ref)
        _REFERENCE[mech] = (vals, [sp.N(e.xreplace(vals), 25) for e in ref])
    vals, ref = _REFERENCE[mech]
    got = [sp.N(e.xreplace(vals), 25) for e in eqs]
    scale = max(abs(r) for r in ref)
    return float(max(abs(a - b) for a, b in zip(got, ref)) / scale)


#: The paper's five-link size in 3D, for the methods that compose it in seconds at most: the
#: goal "3D n=5 in at most 50 ms" is checked in every profile.
FAST_3D5 = ("lagrange", "matrix", "recurrence")


def _cases(sw):
    out = []
    for dim, ns in ((2, sw.compose_2d), (3, sw.compose_3d)):
        for n in ns:
            for topo in ("chain", "branched") if n > 1 else ("chain",):
                out += [(m, n, dim, topo) for m in COMPOSERS]
    if 5 not in sw.compose_3d:
        out += [(m, 5, 3, "chain") for m in FAST_3D5]
    out += [(m, n, 3, "chain") for n in sw.compose_3d_fast if n not in sw.compose_3d for m in ("matrix", "recurrence")]
    return out


def pytest_generate_tests(metafunc):
    if "compose_case" in metafunc.fixturenames:
        cases = _cases(current(metafunc.config.getoption("--sweep")))
        metafunc.parametrize("compose_case", cases, ids=[f"{m}-{t}{n}-{d}d" for m, n, d, t in cases])


def test_compose(benchmark, sweep, compose_case, request):
    method, n, dim, topo = compose_case
    mech = model(n, dim, topo)
    benchmark.group = f"compose-{dim}d"
    # which rows run is predicted from the row's size (bench/perf/profiles.py), never timed: the
    # same rows run on every machine; a row that runs gets LOAD_ALLOWANCE times the budget as its limit
    reason = predicted_skip(method, n, dim, sweep.compose_budget)
    if reason:
        request.node.user_properties.append((OVER_BUDGET, [method, n, dim, topo, reason]))
        pytest.skip(f"{method}: {reason}")
    compose = _composer(method, LOAD_ALLOWANCE * sweep.compose_budget)
    if method not in _WARM:  # imports and first-use set-up are not part of composing
        compose(model(1, dim, "chain"))
        _WARM.add(method)
    rounds = 5 if method in ("matrix", "recurrence") else 1
    benchmark.extra_info.update(method=method, n=n, dim=dim, topology=topo, mechanism=mech.name)
    benchmark.extra_info["predicted_seconds"] = predicted_seconds(method, n, dim)
    try:
        eqs = benchmark.pedantic(compose, args=(mech,), setup=_clear_caches, rounds=rounds, iterations=1)
    except Exception as e:  # noqa: BLE001
        if getattr(e, "skip_reason", None):  # over LOAD_ALLOWANCE x the budget: the prediction was wrong
            pytest.fail(f"{method}: predicted {predicted_seconds(method, n, dim):.3g} s, but {e.skip_reason}")
        raise
    assert len(eqs) == mech.dof
    diff = _same_equations(mech, eqs)
    benchmark.extra_info["max_rel_diff_vs_matrix"] = diff
    assert diff < 1e-15, f"{method} composes different equations (relative difference {diff:.2e})"
