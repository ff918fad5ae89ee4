"""Memos keyed on a mechanism or a user's n are bounded (issue 34; the guide: no module globals growing
with user input): a long-running process that derives many mechanisms keeps only the latest few."""

from __future__ import annotations

import pytest

from exo_bench.lagrange import derivation, numeric
from exo_bench.models.machine.memory import BoundedCache
from exo_bench.models.mechanism.presets import chain


def test_the_bounded_cache_forgets_the_least_recent():
    c: BoundedCache[int, int] = BoundedCache(3)
    for k in range(3):
        c[k] = k
    assert c[0] == 0  # read: now the most recent
    c[3] = 3
    assert list(c) == [2, 0, 3]
    assert len(c) == 3 and 1 not in c


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, None])
def test_a_bad_bound_is_named(bad):
    with pytest.raises(ValueError, match=r"field 'maxsize': expected an integer >= 1"):
        BoundedCache(bad)


def _mechanisms(count):
    """``count`` distinct one-link planar chains (their masses differ)."""
    base = chain(1, 2)
    return [base.replace(masses=((1.0 + k / 8, 0.5, 0.25),), name=f"c{k}") for k in range(count)]


def test_numeric_derivations_of_many_mechanisms_stay_bounded():
    """Deriving 20 mechanisms with numbers keeps at most the memo's bound (16): before, every one stayed."""
    derivation.clear_cache()
    try:
        for m in _mechanisms(20):
            derivation.derive(m)
        assert len(derivation._NUMERIC) == derivation._NUMERIC.maxsize == 16
        assert len(derivation._SYMBOLIC) == 1  # one structure
    finally:
        derivation.clear_cache()


def test_lambdified_functions_of_many_mechanisms_stay_bounded(monkeypatch):
    """The lambdified functions' memo is a bounded one: with a bound of 2 for the test, 4 mechanisms leave 2."""
    monkeypatch.setattr(numeric, "_CACHE", BoundedCache(2))
    for m in _mechanisms(4):
        numeric.compile_equations(m)
    assert len(numeric._CACHE) == 2


def test_every_memo_keyed_on_user_input_is_bounded():
    """The module memos keyed on a mechanism or n: bounded (PyDy's compiled functions included)."""
    from exo_bench.bench.perf import peers
    from exo_bench.models.mechanism.symbols import symbols_for

    for memo in (derivation._SYMBOLIC, derivation._NUMERIC, derivation._FAILED, numeric._CACHE, numeric._FAILED):
        assert isinstance(memo, BoundedCache)
    assert isinstance(peers._CACHE, BoundedCache)
    assert symbols_for.cache_parameters()["maxsize"] is not None
