"""``model.derivatives``' products at the edge (issue 34's classes of input applied to issue 36's JVP
and VJP): with ``check`` (the default) a result is never NaN or inf, as the full Jacobians' and
the forward products' are not; with ``check=False`` the values are not validated, but the entries
are still numbers: strings, booleans and Decimals are refused as the main calls refuse them.

One sample of fig1 (2D): no new kernel, no solve."""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.mechanism.presets import fig1

MECH = fig1(2)
Q = np.array([[0.3, 1.0]])
QD = np.array([[0.1, 0.2]])
QDD = np.array([[0.5, 0.1]])
HUGE = np.full((1, 2), 1e308)  # finite, but no product with it is
MODEL: dict = {}


def _derivatives():
    if not MODEL:
        MODEL["m"] = prepare(MECH, "newton-euler")
    return MODEL["m"].derivatives


@pytest.mark.case("P6")
def test_inverse_products_never_return_nan_with_check():
    """inverse_dynamics_vjp with weights of 1e308 and inverse_dynamics_jvp with a direction of 1e308
    returned NaN and inf with check=True (the forward products refuse): they now refuse, naming the
    field of the result and the coordinate; a direction of ordinary size still answers finite."""
    d = _derivatives()
    with pytest.raises(ValueError, match=r"field 'w_dtau_dq'.*coordinate phi1"):
        d.inverse_dynamics_vjp(Q, QD, QDD, HUGE)
    with pytest.raises(ValueError, match=r"field 'dtau'.*coordinate phi1"):
        d.inverse_dynamics_jvp(Q, QD, QDD, HUGE, QD, QDD)
    assert all(np.isfinite(x).all() for x in d.inverse_dynamics_vjp(Q, QD, QDD, QD))
    assert np.isfinite(d.inverse_dynamics_jvp(Q, QD, QDD, QD, QD, QDD)).all()
    d.inverse_dynamics_vjp(Q, QD, QDD, HUGE, check=False)  # without check: values as computed


NOT_NUMBERS = {
    "str": lambda a: a.astype(str),
    "str list": lambda a: a.astype(str).tolist(),
    "bool": lambda a: a != 0,
    "Decimal": lambda a: np.array([[Decimal(float(x)) for x in row] for row in a], dtype=object),
}


@pytest.mark.case("P7")
@pytest.mark.parametrize("kind", sorted(NOT_NUMBERS))
def test_check_false_still_takes_only_numbers(kind):
    """With check=False the derivatives read q of strings ("0.3"), booleans or Decimals as numbers (the
    main calls with check=False refuse all but float64 arrays): they now refuse them naming the field,
    as check=True does. check=False converts nothing (the array gate, models/states/array_gate.py): a list of
    real numbers is refused naming the field too; check=True converts it."""
    d = _derivatives()
    bad = NOT_NUMBERS[kind]
    with pytest.raises(ValueError, match=r"field 'q'.*expected"):
        d.inverse_dynamics(bad(Q), QD, QDD, check=False)
    with pytest.raises(ValueError, match=r"field 'dq'.*expected"):
        d.inverse_dynamics_jvp(Q, QD, QDD, bad(Q), QD, QDD, check=False)
    with pytest.raises(ValueError, match=r"field 'w'.*expected"):
        d.forward_dynamics_vjp(Q, QD, QDD, bad(Q), check=False)
    with pytest.raises(ValueError, match=r"field 'q': expected .*float64.*check=False"):
        d.inverse_dynamics(Q.tolist(), QD, QDD, check=False)
    np.testing.assert_array_equal(d.inverse_dynamics(Q.tolist(), QD, QDD)[0], d.inverse_dynamics(Q, QD, QDD)[0])


@pytest.mark.case("P7")
def test_directions_and_weights_are_numbers_with_check():
    """With check=True too, a JVP's direction or a VJP's weights of strings were read as numbers (only
    their finiteness was checked, after np.asarray(dtype=float)): they are refused naming the field."""
    d = _derivatives()
    with pytest.raises(ValueError, match=r"field 'w': expected an array of real numbers"):
        d.inverse_dynamics_vjp(Q, QD, QDD, QD.astype(str))
    with pytest.raises(ValueError, match=r"field 'dqd': expected an array of real numbers"):
        d.inverse_dynamics_jvp(Q, QD, QDD, QD, QD.astype(str).tolist(), QDD)


@pytest.mark.case("P9")
@pytest.mark.parametrize("call", ["inverse_dynamics", "forward_dynamics"])
def test_the_memory_estimate_comes_before_the_states_are_copied(monkeypatch, call):
    """A call too large for the memory a run may use is refused by its estimate before any work: the
    states were first converted (three (samples, dof) copies of read-only broadcast views: 14.9 GiB
    each at 10^9 samples, a raw MemoryError) and only then estimated. Counted by tracemalloc, not
    timed: the refusal allocates almost nothing."""
    import tracemalloc

    from exo_bench.models.machine import memory
    from exo_bench.models.derivatives import DerivativesTooLarge

    d = _derivatives()
    states = np.broadcast_to(Q[0], (10**6, 2))  # 16 MB per copy; the estimate is ~400 MB
    monkeypatch.setattr(memory, "usable_memory", lambda: 100 * 2**20)
    tracemalloc.start()
    try:
        with pytest.raises(DerivativesTooLarge, match="samples"):
            getattr(d, call)(states, states, states)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2**20, f"{peak / 2**20:.1f} MiB allocated before the refusal"
