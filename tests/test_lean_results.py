"""A lean one-sample call without ``out`` reuses a result it returned before only once nothing refers to
it any more (issue 35; models/runtime/_lean_call.c ``new_result``): numpy's allocation and deallocation were a
third of the call. A result anyone holds, by a name, a view, a buffer or a weak reference, is never
written again, and one whose flags or shape the caller changed is not handed out again. Inverse and
forward dynamics, matrix-factored and newton-euler (their cfuncs share the wrapper)."""

from __future__ import annotations

import weakref

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5

pytest.importorskip("exo_bench.models.runtime._lean_call", reason="the C wrapper is optional (setup.py)")

METHODS = ["matrix-factored", "newton-euler"]


@pytest.fixture(scope="module", params=METHODS)
def case(request):
    mech = exo5(3)
    model = prepare(mech, request.param)
    from exo_bench.models.runtime import _lean_call

    assert isinstance(model._entries.lean, _lean_call.LeanCall)
    states = [tuple(np.ascontiguousarray(a[s]) for a in random_states(mech, 6, seed=11)) for s in range(6)]
    want = [model.inverse_dynamics(*s, check=False).copy() for s in states]
    return model, states, want


def test_a_dropped_result_is_written_again(case):
    """The oracle of reuse: a dropped result comes back as the same object, though new arrays of its
    size were made in between (which would take its memory if it had been freed)."""
    model, states, want = case
    first = model.inverse_dynamics(*states[0], check=False)
    kept = id(first)
    del first
    others = [np.empty(model.dof) for _ in range(4)]
    again = model.inverse_dynamics(*states[1], check=False)
    assert id(again) == kept and all(id(o) != kept for o in others)
    np.testing.assert_array_equal(again, want[1])


@pytest.mark.parametrize("hold", ["name", "view", "buffer", "weakref", "list"])
def test_a_result_anyone_holds_is_never_written_again(case, hold):
    model, states, want = case
    held = []
    for s in range(3):
        r = model.inverse_dynamics(*states[s], check=False)
        held.append({"name": r, "view": r[2:], "buffer": memoryview(r), "weakref": weakref.ref(r), "list": [r]}[hold])
        del r
        for t in range(3, 6):  # more calls, their results dropped
            model.inverse_dynamics(*states[t], check=False)
    for s, h in enumerate(held):
        got = {"view": lambda: np.concatenate([want[s][:2], h]), "buffer": lambda: np.asarray(h)}
        value = h() if hold == "weakref" else h[0] if hold == "list" else got.get(hold, lambda: h)()
        if hold == "weakref" and value is None:
            continue  # freed: nothing to compare
        np.testing.assert_array_equal(value, want[s])


@pytest.mark.parametrize("change", ["read-only", "reshaped"])
def test_a_result_changed_by_its_caller_is_not_handed_out_again(case, change):
    model, states, want = case
    r = model.inverse_dynamics(*states[0], check=False)
    if change == "read-only":
        r.flags.writeable = False
    else:
        r.shape = (3, model.dof // 3)
    del r
    for s in (1, 2, 3):
        got = model.inverse_dynamics(*states[s], check=False)
        assert got.shape == (model.dof,) and got.flags.writeable and got.flags.owndata
        np.testing.assert_array_equal(got, want[s])


def test_forward_results_follow_the_same_rule(case):
    model, states, want = case
    q, qd, _ = states[0]
    held = model.forward_dynamics(q, qd, want[0], check=False)
    first = held.copy()
    for s in range(1, 6):
        model.forward_dynamics(*states[s][:2], want[s], check=False)
    np.testing.assert_array_equal(held, first)
    np.testing.assert_allclose(held, states[0][2], rtol=1e-9, atol=1e-9 * np.abs(states[0][2]).max())
