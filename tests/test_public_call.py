"""The public one-sample call and its checked path answer alike (issue 47): PreparedModel's
``inverse_dynamics`` and ``forward_dynamics`` offer one sample to the kernel's compiled entry and run the
checked path (``_dynamics``) only where it declines. What it declines reaches the checked path, which
validates and names the problem. (How many of the project's Python functions a call runs:
tests/test_call_frames.py.)"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.api import prepare
from exo_bench.models.motion import smooth_random_motion
from exo_bench.models.presets import exo5


@pytest.fixture(scope="module")
def models():
    mech = exo5(3)
    mo = smooth_random_motion(mech, np.linspace(0.0, 1.0, 3), seed=2)
    q, qd, qdd = (np.ascontiguousarray(a[0]) for a in (mo.q, mo.qd, mo.qdd))
    mf, ne = prepare(mech, "matrix-factored"), prepare(mech, "newton-euler")
    return mech, (mf, ne), (q, qd, qdd, mf.inverse_dynamics(q, qd, qdd, check=False).copy())


def test_the_same_numbers_as_the_python_path(models):
    mech, prepared, (q, qd, qdd, tau) = models
    for m in prepared:
        want = m._dynamics(False, q, qd, qdd, False, None, None)
        out = np.empty(mech.dof)
        assert m.inverse_dynamics(q, qd, qdd, check=False, out=out) is out
        assert np.array_equal(out, want)
        assert np.array_equal(m.inverse_dynamics(q, qd, qdd), want)
        assert np.array_equal(m.inverse_dynamics(q=q, qd=qd, qdd=qdd), want)  # by name
        assert np.array_equal(type(m).inverse_dynamics(m, q, qd, qdd, check=False), want)
        fwd = m._dynamics(True, q, qd, tau, True, None, None)
        assert np.array_equal(m.forward_dynamics(q, qd, tau), fwd)


def test_a_call_without_check_is_checked(models):
    """``check`` omitted is ``check=True``: the compiled entry validates (or declines) and the error names the field."""
    mech, prepared, (q, qd, qdd, tau) = models
    bad = q.copy()
    bad[mech.dof - 1] = -1.0  # a negative rod length
    for m in prepared:
        for call in (lambda: m.inverse_dynamics(bad, qd, qdd), lambda: m.inverse_dynamics(bad, qd, qdd, 1)):
            with pytest.raises(ValueError, match="q"):
                call()
        with pytest.raises(ValueError, match="q"):
            m.forward_dynamics(bad, qd, tau)


def test_what_the_entry_declines_is_refused_by_name(models):
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
