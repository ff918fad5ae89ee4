"""The fast symbolic construction gives sympy's own canonical expressions, fast."""

import random
from functools import cmp_to_key

import pytest
import sympy as sp
from sympy.core.basic import Basic

from exo_bench.matrix_method import symbolic
from exo_bench.matrix_method.symbolic import Poly, order_key
from exo_bench.models.mechanism.presets import exo5, random_tree


def _random_exprs(seed, count=60):
    rng = random.Random(seed)
    x, y, z = sp.symbols("x y z", real=True)
    m = sp.Symbol("m1_0", nonnegative=True)
    atoms = [
        x,
        y,
        z,
        m,
        sp.cos(x),
        sp.sin(x - y),
        sp.cos(y - z),
        x**2,
        sp.Rational(3, 7),
        sp.Integer(-2),
        sp.Float(1.5),
        m * x + 2 * y,
    ]
    out = []
    for _ in range(count):
        k = rng.randint(1, 4)
        out.append(sp.Mul(*rng.sample(atoms, k)) if rng.random() < 0.7 else sp.Add(*rng.sample(atoms, k)))
    return out


@pytest.mark.parametrize("seed", range(5))
def test_order_key_sorts_like_sympys_comparison(seed):
    exprs = _random_exprs(seed)
    assert sorted(exprs, key=order_key) == sorted(exprs, key=cmp_to_key(Basic.compare))


@pytest.mark.parametrize("mech", [random_tree(3, 2, 1), random_tree(4, 3, 2), exo5(3)], ids=lambda m: m.name)
@pytest.mark.parametrize("symbolic_parameters", [False, True])
def test_emitted_expressions_are_what_sympys_constructors_give(mech, symbolic_parameters):
    for e in symbolic.compose_equations(mech, symbolic_parameters):
        assert sp.Add(*e.args) == e
        for t in e.args:
            assert t.func(*t.args) == t


def test_polynomial_arithmetic_matches_sympy():
    G = symbolic.Generators(3, 3, symbolic_parameters=False)
    gens = list(G.gen.values())
    rng = random.Random(3)
    for _ in range(30):
        a = sum((rng.randint(-3, 3) * rng.choice(gens) * rng.choice(gens) for _ in range(4)), Poly({}))
        b = sum((rng.randint(-3, 3) * rng.choice(gens) for _ in range(3)), Poly({})) + 2
        ea, eb = G.expr(a), G.expr(b)
        assert sp.expand(G.expr(a * b) - ea * eb) == 0
        assert sp.expand(G.expr(a - b) - (ea - eb)) == 0
        assert sp.expand(G.expr(a**2) - ea**2) == 0
    assert Poly({}) == 0 and (Poly({}) + 0) == 0
