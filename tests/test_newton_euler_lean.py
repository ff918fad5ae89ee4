"""newton-euler's one sample in one compiled call (issue 35): the per-sample inverse pass behind the
compiled validate-and-compute entry (models/newton_euler/compiled.py), held by the ``lean`` kernel object.
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


def _bits(a):
    return np.asarray(a).view(np.int64).tolist()


@pytest.mark.parametrize("tree", [*MECHS, "exo5-2d", "exo5-3d"])
def test_the_lean_call_is_bit_identical_to_the_per_sample_kernel(tree):
    mech = exo5(int(tree[-2])) if isinstance(tree, str) else random_tree(*tree)
    model = prepare(mech, "newton-euler")
    assert model._entries.inverse_fast is not None
    q, qd, qdd = random_states(mech, 6, seed=5)
    q[4, 0], qd[5, -1] = np.nan, np.inf  # never hidden: the same NaN as the kernel's
    for s in range(q.shape[0]):
        one = [np.ascontiguousarray(a[s]) for a in (q, qd, qdd)]
        want = model._entries.inverse_one(*one, np.empty(mech.dof))
        out = np.full(mech.dof, -1.0)
        assert model._entries.inverse_fast(*one, out, False) == 0  # the compiled entry took it
        assert _bits(out) == _bits(want)
        assert _bits(model.inverse_dynamics(*one, check=False)) == _bits(want)
        if np.isfinite(q[s]).all() and np.isfinite(qd[s]).all():
            assert _bits(model.inverse_dynamics(*one)) == _bits(want)  # check=True: the same numbers


def test_the_lean_call_declines_what_it_does_not_take():
    """A strided array, an overlapping ``out``, with ``check=True`` a state the validation refuses (NaN):
    declined (a code, nothing written); the public call then checks and names the field. A batch, a
    float32 array or a read-only ``out`` never reach the entry (the public call checks the type, the
    dimensions, the dtype and the flag first: numba's unboxing trusts them) and are named or run as a batch.
    (A valid ``check=True`` sample is taken: tests/test_checked_lean.py.)"""
    mech = exo5(3)
    model = prepare(mech, "newton-euler")
    q, qd, qdd = (np.ascontiguousarray(a[0]) for a in random_states(mech, 1, seed=6))
    out = np.full(mech.dof, 7.0)
    for args in [
        (np.repeat(q, 2)[::2], qd, qdd, out, False),
        (np.where(np.arange(mech.dof) == 3, np.nan, q), qd, qdd, out, True),
        (q, qd, out, out, False),
    ]:
        assert model._entries.inverse_fast(*args) != 0
        assert (out == 7.0).all()
    with pytest.raises(ValueError, match="field 'out'.*overlaps 'qdd'"):
        model.inverse_dynamics(q, qd, out, check=False, out=out)
    with pytest.raises(ValueError, match="field 'q'"):
        model.inverse_dynamics(q.astype(np.float32), qd, qdd, check=False, out=out)
    ro = np.empty(mech.dof)
    ro.flags.writeable = False
    with pytest.raises(ValueError, match="field 'out'.*read-only"):
        model.inverse_dynamics(q, qd, qdd, check=False, out=ro)
    assert model.inverse_dynamics(q[None], qd[None], qdd[None], check=False).shape == (1, mech.dof)
