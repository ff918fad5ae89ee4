"""The public one-sample call runs no Python frame (issue 35's ``check=False, out=`` goal): PreparedModel's
``inverse_dynamics`` and ``forward_dynamics`` are the extension's ``PublicCall`` (models/runtime/lean_call.py
:func:`public_call`), which offers the call to the instance's lean entry in C and runs the Python function
only where the entry declines it. What it declines still reaches the Python path, which validates and
names the problem; the descriptor keeps the function's name, docstring and signature."""

from __future__ import annotations

import inspect
import pickle
import sys

import numpy as np
import pytest

from exo_bench.api import prepare
from exo_bench.models.runtime.lean_call import extension
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.runtime.prepared import PreparedModel
from exo_bench.models.mechanism.presets import exo5

pytestmark = pytest.mark.skipif(extension() is None, reason="models/runtime/_lean_call.c was not built (optional)")


@pytest.fixture(scope="module")
def models():
    mech = exo5(3)
    mo = smooth_random_motion(mech, np.linspace(0.0, 1.0, 3), seed=2)
    q, qd, qdd = (np.ascontiguousarray(a[0]) for a in (mo.q, mo.qd, mo.qdd))
    mf, ne = prepare(mech, "matrix-factored"), prepare(mech, "newton-euler")
    return mech, (mf, ne), (q, qd, qdd, mf.inverse_dynamics(q, qd, qdd, check=False).copy())


def _python_calls(call) -> int:
    """Python functions entered while ``call()`` runs (sys.setprofile's 'call' events)."""
    seen = []
    sys.setprofile(lambda frame, event, arg: seen.append(frame.f_code.co_name) if event == "call" else None)
    try:
        call()
    finally:
        sys.setprofile(None)
    return len(seen)


def test_one_sample_calls_run_no_python_frame(models):
    mech, prepared, (q, qd, qdd, tau) = models
    out = np.empty(mech.dof)
    for m in prepared:
        for call in (
            lambda: m.inverse_dynamics(q, qd, qdd, check=False, out=out),
            lambda: m.inverse_dynamics(q, qd, qdd, check=False),
            lambda: m.inverse_dynamics(q, qd, qdd),
            lambda: m.inverse_dynamics(q, qd, qdd, False, out),
            lambda: m.forward_dynamics(q, qd, tau),
            lambda: m.forward_dynamics(q, qd, tau, check=False, out=out),
        ):
            call()  # first use
            assert _python_calls(call) == 1, f"{m.method}: a Python frame beside the caller's lambda"
    # the checker can fail: a batch goes through the Python path
    assert _python_calls(lambda: prepared[0].inverse_dynamics(q[None], qd[None], qdd[None])) > 1


def test_the_same_numbers_as_the_python_path(models):
    mech, prepared, (q, qd, qdd, tau) = models
    for m in prepared:
        python = PreparedModel.inverse_dynamics.__wrapped__
        want = python(m, q, qd, qdd, check=False)
        out = np.empty(mech.dof)
        assert m.inverse_dynamics(q, qd, qdd, check=False, out=out) is out
        assert np.array_equal(out, want)
        assert np.array_equal(m.inverse_dynamics(q, qd, qdd), want)
        assert np.array_equal(m.inverse_dynamics(q=q, qd=qd, qdd=qdd), want)  # by name: the Python path
        assert np.array_equal(PreparedModel.inverse_dynamics(m, q, qd, qdd, check=False), want)
        fwd = PreparedModel.forward_dynamics.__wrapped__(m, q, qd, tau)
        assert np.array_equal(m.forward_dynamics(q, qd, tau), fwd)


def test_a_call_without_check_is_checked(models):
    """``check`` omitted is ``check=True``: the C path validates (or declines) and the error names the field."""
    mech, prepared, (q, qd, qdd, tau) = models
    bad = q.copy()
    bad[mech.dof - 1] = -1.0  # a negative rod length
    for m in prepared:
        for call in (lambda: m.inverse_dynamics(bad, qd, qdd), lambda: m.inverse_dynamics(bad, qd, qdd, 1)):
            with pytest.raises(ValueError, match="q"):
                call()
        with pytest.raises(ValueError, match="q"):
            m.forward_dynamics(bad, qd, tau)


def test_what_the_c_path_declines_is_refused_by_name(models):
    mech, prepared, (q, qd, qdd, tau) = models
    whole = np.zeros(2 * mech.dof)
    for m in prepared:
        overlap = whole[1 : mech.dof + 1]
        q2 = whole[: mech.dof]
        q2[:] = q
        with pytest.raises(ValueError, match="out"):  # out overlaps q: refused even with check=False
            m.inverse_dynamics(q2, qd, qdd, check=False, out=overlap)
        with pytest.raises(ValueError):
            m.inverse_dynamics(q[:-1], qd, qdd, check=False)
        with pytest.raises(TypeError):
            m.inverse_dynamics(q, qd, qdd, check=False, bogus=1)
        f_ext = np.zeros((mech.nlinks, 3, mech.dim))
        assert np.allclose(m.inverse_dynamics(q, qd, qdd, f_ext=f_ext), tau, rtol=1e-12, atol=1e-9)


def test_the_descriptor_is_the_functions_likeness(models):
    mech, (mf, _), _ = models
    for name in ("inverse_dynamics", "forward_dynamics"):
        d = vars(PreparedModel)[name]
        assert getattr(PreparedModel, name) is d and getattr(type(mf), name) is d
        assert d.__name__ == name and d.__doc__ == d.__wrapped__.__doc__ and d.__doc__
        assert inspect.isroutine(d)
        assert (
            list(inspect.signature(getattr(mf, name)).parameters)[:5]
            == list(inspect.signature(d.__wrapped__).parameters)[1:6]
        )
        bound = getattr(mf, name)
        assert bound.__self__ is mf and pickle.loads(pickle.dumps(bound)).__name__ == name


def test_the_entries_are_read_as_they_are_now(models):
    """The descriptor reads ``_entries`` from its slot at each call (only the offset is kept, while the
    type is unchanged): entries replaced on the instance, or a class whose ``_entries`` is no slot, are
    honoured (the Python path then runs, with the same numbers)."""
    from exo_bench.models.runtime.kernels import Entries

    mech, _, (q, qd, qdd, tau) = models
    m = prepare(mech, "matrix-factored")
    want = m.inverse_dynamics(q, qd, qdd, check=False)
    assert _python_calls(lambda: m.inverse_dynamics(q, qd, qdd, check=False)) == 1
    lean, m._entries = m._entries, Entries(inverse_one=m._entries.inverse_one)
    assert _python_calls(lambda: m.inverse_dynamics(q, qd, qdd, check=False)) > 1
    assert np.array_equal(m.inverse_dynamics(q, qd, qdd, check=False), want)
    m._entries = lean

    class Shadowed(type(m)):
        @property
        def _entries(self):  # no slot: the descriptor asks by name
            return Entries(inverse_one=lean.inverse_one)

    s = Shadowed.__new__(Shadowed)
    s.__dict__.update(m.__dict__)
    assert _python_calls(lambda: s.inverse_dynamics(q, qd, qdd, check=False)) > 1
    assert np.array_equal(s.inverse_dynamics(q, qd, qdd, check=False), want)
