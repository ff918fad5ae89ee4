"""The default one-sample call (``check=True``) validated and computed in one compiled call, the kernel's
validate-and-compute entry (``inverse_fast``: models/validation_pass.py ``one_sample``, then the kernel);
whatever it refuses or does not take goes to PreparedModel's checked path, which names the problem. No wall clock: the tests assert which
path ran (by refusing the Python path's check), the same bits as ``check=False``, and the messages.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.motion import random_states
from exo_bench.models.presets import exo5

METHODS = ("matrix-factored", "newton-euler")


@pytest.fixture(scope="module", params=METHODS)
def model(request):
    return prepare(exo5(3), request.param)


def _sample(model, seed=3):
    q, qd, qdd = random_states(model.mechanism, 1, seed)
    return np.ascontiguousarray(q[0]), np.ascontiguousarray(qd[0]), np.ascontiguousarray(qdd[0])


def test_a_valid_sample_never_reaches_the_python_check(model, monkeypatch):
    """A valid C-ordered float64 sample is validated and computed in one compiled call: the Python check is never
    called (it would raise), with or without ``out``, and the answer is ``check=False``'s bit for bit
    (seen failing before: the checked call ran checked_states)."""
    from exo_bench.models import prepared

    q, qd, qdd = _sample(model)
    want = model.inverse_dynamics(q, qd, qdd, check=False)

    def refuse(*args, **kw):
        raise AssertionError("the Python check ran")

    monkeypatch.setattr(prepared, "checked_states", refuse)
    assert np.array_equal(model.inverse_dynamics(q, qd, qdd), want)
    out = np.full(model.dof, 7.0)
    assert model.inverse_dynamics(q, qd, qdd, out=out) is out and np.array_equal(out, want)


@pytest.mark.parametrize(
    "what, match",
    [
        ("nan qd", "field 'qd' sample 0 coordinate .*: expected a finite number"),
        ("inf q", "field 'q' sample 0 coordinate .*: expected a finite number"),
        ("negative length", "expected a rod length >= 0"),
        ("overflow", "the forces would overflow float64"),
    ],
)
def test_a_refused_sample_is_named_and_out_untouched(model, what, match):
    """What the validation refuses goes to the Python path, which names it; ``out`` is not written."""
    q, qd, qdd = _sample(model, 5)
    if what == "nan qd":
        qd[4] = np.nan
    elif what == "inf q":
        q[1] = np.inf
    elif what == "negative length":
        q[-2] = -0.5
    else:
        qdd[3] = 1e300
    out = np.full(model.dof, 7.0)
    with pytest.raises(ValueError, match=match):
        model.inverse_dynamics(q, qd, qdd, out=out)
    assert (out == 7.0).all()


class _Sub(np.ndarray):
    pass


@pytest.mark.parametrize("form", ["subclass", "strided", "float32", "read-only out", "overlapping out"])
def test_what_the_entry_does_not_take_goes_to_the_python_check(model, monkeypatch, form):
    """Subclasses, other layouts and dtypes, an ``out`` it cannot write apart from the inputs: the Python
    path runs (its check is called once) and answers as ``check=False`` on the converted sample."""
    from exo_bench.models import prepared

    q, qd, qdd = _sample(model, 7)
    want = model.inverse_dynamics(q, qd, qdd, check=False)
    calls = []
    real = prepared.checked_states
    monkeypatch.setattr(prepared, "checked_states", lambda *a, **k: calls.append(1) or real(*a, **k))
    out = None
    if form == "subclass":
        q = q.view(_Sub)
    elif form == "strided":
        q = np.repeat(q, 2)[::2]
    elif form == "float32":
        qd = qd.astype(np.float32)
        want = model.inverse_dynamics(q, qd.astype(np.float64), qdd, check=False)
    elif form == "read-only out":
        out = np.empty(model.dof)
        out.flags.writeable = False
    else:
        out = qdd  # the result overwrites an input (the Python path computes, then copies)
    if form == "read-only out":
        with pytest.raises(ValueError):
            model.inverse_dynamics(q, qd, qdd, out=out)
    else:
        got = model.inverse_dynamics(q, qd, qdd, out=out)
        assert np.array_equal(np.asarray(got), want)
    assert calls == [1]
