"""newton-euler's lean one-sample call (issue 35): the per-sample inverse pass as a cfunc behind the
C wrapper (models/newton_euler/lean.py, models/runtime/lean_call.py), held by the ``lean`` kernel object.
Its forces are bit-identical to the per-sample kernel's (and so to check=True's and to the batch
of one), on 2D/3D chains and trees, NaN states included; it declines what it does not take."""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, random_tree

#: Seeded random trees (n, dim, seed) of tests/test_newton_euler.py (several roots, signs -1) and exo5.
MECHS = [(1, 2, 0), (4, 2, 1), (9, 2, 11), (1, 3, 3), (5, 3, 4), (9, 3, 12)]


def _built() -> bool:
    try:
        from exo_bench.models.runtime import _lean_call  # noqa: F401
    except ImportError:
        return False
    return True


needs_c = pytest.mark.skipif(not _built(), reason="models/runtime/_lean_call.c was not built here (no C compiler)")


def _bits(a):
    return np.asarray(a).view(np.int64).tolist()


@needs_c
@pytest.mark.parametrize("tree", [*MECHS, "exo5-2d", "exo5-3d"])
def test_the_lean_call_is_bit_identical_to_the_per_sample_kernel(tree):
    mech = exo5(int(tree[-2])) if isinstance(tree, str) else random_tree(*tree)
    model = prepare(mech, "newton-euler")
    from exo_bench.models.runtime import _lean_call

    assert isinstance(model._entries.lean, _lean_call.LeanCall)
    q, qd, qdd = random_states(mech, 6, seed=5)
    q[4, 0], qd[5, -1] = np.nan, np.inf  # never hidden: the same NaN as the kernel's
    for s in range(q.shape[0]):
        one = [np.ascontiguousarray(a[s]) for a in (q, qd, qdd)]
        want = model._entries.inverse_one(*one, np.empty(mech.dof))
        out = np.full(mech.dof, -1.0)
        assert model._entries.lean(*one, False, out) is out  # the C call took it
        assert _bits(out) == _bits(want)
        assert _bits(model.inverse_dynamics(*one, check=False)) == _bits(want)
        if np.isfinite(q[s]).all() and np.isfinite(qd[s]).all():
            assert _bits(model.inverse_dynamics(*one)) == _bits(want)  # check=True: the same numbers


@needs_c
def test_the_lean_call_declines_what_it_does_not_take():
    """A batch, a strided or float32 array, a read-only or overlapping ``out``, with ``check=True`` a state
    the validation refuses (NaN) or a flag that is not ``True`` itself: declined (None, nothing written);
    the public call then checks and names the field, or runs the batch. (A valid ``check=True`` sample
    is taken: tests/test_checked_lean.py.)"""
    mech = exo5(3)
    model = prepare(mech, "newton-euler")
    q, qd, qdd = (np.ascontiguousarray(a[0]) for a in random_states(mech, 1, seed=6))
    out = np.full(mech.dof, 7.0)
    ro = np.empty(mech.dof)
    ro.flags.writeable = False
    for args in [
        (q[None], qd[None], qdd[None], False, out[None]),
        (np.repeat(q, 2)[::2], qd, qdd, False, out),
        (q.astype(np.float32), qd, qdd, False, out),
        (q, qd, qdd, False, ro),
        (np.where(np.arange(mech.dof) == 3, np.nan, q), qd, qdd, True, out),
        (q, qd, qdd, 1, out),
        (q, qd, out, False, out),
    ]:
        assert model._entries.lean(*args) is None
        assert (out == 7.0).all()
    with pytest.raises(ValueError, match="field 'out'.*overlaps 'qdd'"):
        model.inverse_dynamics(q, qd, out, check=False, out=out)
    with pytest.raises(ValueError, match="field 'q'"):
        model.inverse_dynamics(q.astype(np.float32), qd, qdd, check=False, out=out)
