"""Forward dynamics of one sample in one compiled call (the ``forward_fast`` entries of ``cholesky-forward``
and ``tree-forward``): with ``check=True`` the validation of one sample, then the compiled common-case checks
and the forward passes; the result is taken only where the checks clear the state and the answer is finite.
Everything else goes to PreparedModel's checked path, which decides and names the problem. No wall clock:
the tests assert which path ran (by refusing the Python path), the Python path's bits, the messages and that
``out`` is untouched on a refusal. The Python path is called directly (``_python``) for its bits.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.motion import random_states
from exo_bench.models.presets import exo5
from exo_bench.models.singularity import SingularConfigurationError

METHODS = ("matrix-factored", "newton-euler")


@pytest.fixture(scope="module", params=[(m, d) for m in METHODS for d in (2, 3)], ids=lambda p: f"{p[0]}-{p[1]}d")
def model(request):
    method, dim = request.param
    return prepare(exo5(dim), method)


def _sample(model, seed=3):
    q, qd, qdd = random_states(model.mechanism, 1, seed)
    tau = model.inverse_dynamics(q, qd, qdd, check=False)
    return tuple(np.ascontiguousarray(a[0]) for a in (q, qd, tau))


def _bits(a):
    return np.asarray(a).view(np.int64).tolist()


def _python(model, q, qd, tau, check=True, out=None):
    """The public call's checked path (what runs where the one-sample entry declines)."""
    return model._dynamics(True, q, qd, tau, check, out, None)


def test_the_entry_is_bound(model):
    assert model._entries.forward_fast is not None


def test_a_valid_sample_never_reaches_the_python_path(model, monkeypatch):
    """A valid C-ordered float64 sample is validated, checked and computed in one compiled call, with or without ``out``,
    ``check`` True or False: neither the Python check nor the Python entries run (they would raise), and
    the bits are the Python path's (seen failing with the entry removed: the Python check ran)."""
    from exo_bench.models import prepared

    q, qd, tau = _sample(model)
    want = {c: _python(model, q, qd, tau, check=c) for c in (True, False)}

    def refuse(*args, **kw):
        raise AssertionError("the Python path ran")

    monkeypatch.setattr(prepared, "checked_states", refuse)
    monkeypatch.setattr(prepared, "gate_states", refuse)
    for name in ("forward_checked", "forward_one"):
        monkeypatch.setattr(model._entries, name, refuse)
    for check in (True, False):
        assert _bits(model.forward_dynamics(q, qd, tau, check=check)) == _bits(want[check])
        out = np.full(model.dof, 7.0)
        assert model.forward_dynamics(q, qd, tau, check=check, out=out) is out
        assert _bits(out) == _bits(want[check])


@pytest.mark.parametrize("seed", [1, 2, 5])
def test_the_same_bits_as_the_python_path(model, seed):
    """Random states (3D: some rods near the vertical, short rods): the compiled call answers the Python path's
    bits, or declines where that path refuses (the same error)."""
    q, qd, tau = _sample(model, seed)
    for check in (True, False):
        try:
            want = _python(model, q, qd, tau, check=check)
        except ValueError as e:
            with pytest.raises(type(e)):
                model.forward_dynamics(q, qd, tau, check=check)
            continue
        assert _bits(model.forward_dynamics(q, qd, tau, check=check)) == _bits(want)


def _singular(model, what):
    q, qd, tau = _sample(model)
    n, dim = model.mechanism.nlinks, model.mechanism.dim
    if what == "zero length":
        q[-1] = 0.0
    elif what == "vertical rod":
        if dim == 2:
            pytest.skip("2D: no rod is vertical")
        q[n + 1] = np.pi / 2
    elif what == "nan tau":
        tau[2] = np.nan
    elif what == "inf qd":
        qd[0] = np.inf
    return q, qd, tau


@pytest.mark.parametrize(
    "what, error, match",
    [
        ("zero length", SingularConfigurationError, "sample 0: .*length"),
        ("vertical rod", SingularConfigurationError, "sample 0: .*vertical"),
        ("nan tau", ValueError, "field 'tau' sample 0 coordinate .*: expected a finite number"),
        ("inf qd", ValueError, "field 'qd' sample 0 coordinate .*: expected a finite number"),
    ],
)
def test_a_refused_sample_is_named_and_out_untouched(model, what, error, match):
    """What the validation or the checks refuse goes to the Python path, which names it; ``out`` is not
    written (the public call hands the entry a scratch array, never ``out``, and copies only when it is done)."""
    q, qd, tau = _singular(model, what)
    out = np.full(model.dof, 7.0)
    with pytest.raises(error, match=match):
        model.forward_dynamics(q, qd, tau, out=out)
    assert (out == 7.0).all()
    scratch = np.full(model.dof, 7.0)
    assert model._entries.forward_fast(q, qd, tau, scratch, True) != 0  # declined
    assert (out == 7.0).all()


def test_check_false_never_hides_a_nan(model):
    """``check=False`` with a NaN in ``tau``: the NaN comes back, bit for bit the Python path's answer."""
    q, qd, tau = _singular(model, "nan tau")
    want = _python(model, q, qd, tau, check=False)
    assert np.isnan(want).any()
    assert _bits(model.forward_dynamics(q, qd, tau, check=False)) == _bits(want)


@pytest.mark.parametrize("form", ["strided", "float32", "read-only out", "out is tau", "subclass", "batch"])
def test_what_the_entry_does_not_take_gets_the_python_paths_answer(model, form):
    """Layouts the entry does not take are declined (nothing written) or never offered to it (what numba's
    unboxing trusts: the type, the dimensions, the dtype), and the public call answers as its Python path
    does."""
    q, qd, tau = _sample(model)
    want = _python(model, q, qd, tau)
    out = np.full(model.dof, 7.0)
    args = [q, qd, tau]
    if form == "strided":
        args[0] = np.repeat(q, 2)[::2]
    elif form == "float32":
        args[1] = qd.astype(np.float32)
        want = _python(model, q, qd.astype(np.float32), tau)
    elif form == "read-only out":
        out.flags.writeable = False
    elif form == "out is tau":
        out = args[2] = tau.copy()
    elif form == "subclass":
        args[0] = q.view(type("Sub", (np.ndarray,), {}))
    if form == "batch":
        assert model.forward_dynamics(q[None], qd[None], tau[None]).shape == (1, model.dof)  # the batched route
        return
    if form == "strided":
        assert model._entries.forward_fast(*args, np.empty(model.dof), True) != 0
    if form == "read-only out":
        with pytest.raises(ValueError, match="out"):
            model.forward_dynamics(*args, out=out)
        return
    assert model.forward_dynamics(*args, out=out) is out
    assert _bits(out) == _bits(want)


def test_each_call_without_out_returns_a_new_array(model):
    """Without ``out`` the call allocates the result: a new array each call, never one handed out before,
    for inverse and forward dynamics, checked or not."""
    q, qd, tau = _sample(model)
    for call, third in ((model.forward_dynamics, tau), (model.inverse_dynamics, tau)):
        for check in (True, False):
            first = call(q, qd, third, check=check)
            kept = first.copy()
            second = call(q, qd, third, check=check)
            assert second is not first and not np.shares_memory(first, second)
            assert first.flags.owndata and first.flags.writeable and first.flags.c_contiguous
            assert _bits(first) == _bits(kept) == _bits(second)
