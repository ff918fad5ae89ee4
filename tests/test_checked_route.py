"""A checked batch runs the route of ``check=False`` (issue 35): after the validation pass, the same
kernel entry on the whole batch, so ``check`` never changes the route nor the numbers (and costs
only the pass: the goal "checked batch <= 1.25x unchecked" is a benchmark row, not asserted here).
Counted, not timed: the entries are wrapped and their calls counted."""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.api import prepare
from exo_bench.models.motion import smooth_random_motion
from exo_bench.models.presets import exo5

MECH = exo5(3)
#: The methods whose kernels supply a whole-batch entry (inverse_whole) by default.
WHOLE = ("matrix-factored", "newton-euler")


def _states(samples: int, seed: int):
    mo = smooth_random_motion(MECH, np.linspace(0.0, 2.0, samples), seed=seed)
    return mo.q, mo.qd, mo.qdd


def _counting(model, **entries):
    """Count the calls of the model's entries named by ``entries`` (key: the count's name, value: the
    model's attribute), each still calling the entry it replaces."""
    calls = dict.fromkeys(entries, 0)

    def counted(key, entry):
        def call(*a):
            calls[key] += 1
            return entry(*a)

        return call

    for key, attr in entries.items():
        setattr(model, attr, counted(key, getattr(model, attr)))
    return calls


@pytest.mark.parametrize("method", WHOLE)
@pytest.mark.parametrize("with_out", [False, True])
def test_a_checked_batch_runs_the_unchecked_route(method, with_out):
    """A batch longer than a chunk: check=True calls the whole-batch entry once (as check=False
    does), never the chunked one, and the results are bit-identical, with and without ``out``."""
    model = prepare(MECH, method)
    assert model._entries.inverse_whole is not None
    model.chunk_samples = 7
    q, qd, qdd = _states(50, 3)
    calls = _counting(model._entries, whole="inverse_whole", chunk="inverse_chunk")
    outs = [np.empty_like(q), np.empty_like(q)] if with_out else [None, None]
    checked = model.inverse_dynamics(q, qd, qdd, out=outs[0])
    assert calls == {"whole": 1, "chunk": 0}
    unchecked = model.inverse_dynamics(q, qd, qdd, check=False, out=outs[1])
    assert calls == {"whole": 2, "chunk": 0}
    assert checked.view(np.int64).tolist() == unchecked.view(np.int64).tolist()
    if with_out:
        assert checked is outs[0] and unchecked is outs[1]


@pytest.mark.parametrize("method", WHOLE)
def test_a_checked_out_that_overlaps_an_input_still_gets_the_result(method):
    """check=True converts and copies as needed: an ``out`` that is an input (in place) gets the
    forces of the states as they were, the numbers of check=False on separate arrays."""
    model = prepare(MECH, method)
    q, qd, qdd = _states(20, 4)
    want = model.inverse_dynamics(q, qd, qdd, check=False)
    qdd = qdd.copy()
    got = model.inverse_dynamics(q, qd, qdd, out=qdd)
    assert got is qdd
    assert got.view(np.int64).tolist() == want.view(np.int64).tolist()


@pytest.mark.parametrize("method", WHOLE)
def test_a_checked_sample_runs_the_entry_of_check_false(method):
    """One sample, check=True: the compiled one-sample entry of check=False runs it (validating first),
    the per-sample entry only where that one declines; the same bits."""
    model = prepare(MECH, method)
    assert model._entries.inverse_fast is not None
    calls = _counting(model._entries, lean="inverse_fast", one="inverse_one")
    q, qd, qdd = (np.ascontiguousarray(a[0]) for a in _states(3, 5))
    checked = model.inverse_dynamics(q, qd, qdd)
    assert calls == {"lean": 1, "one": 0}
    unchecked = model.inverse_dynamics(q, qd, qdd, check=False)
    assert calls == {"lean": 2, "one": 0}
    assert checked.view(np.int64).tolist() == unchecked.view(np.int64).tolist()
