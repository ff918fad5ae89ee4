"""The recycled results (models/runtime/prepared.py): a result is reused only once nothing outside the pool
refers to it, so a result the caller holds (or any view of it) is never written again."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from conftest import run_in_threads

from exo_bench import prepare
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.mechanism.presets import chain
from exo_bench.models.runtime.prepared import MIN_BYTES, RECYCLES, ResultPool

pytestmark = pytest.mark.skipif(not RECYCLES, reason="free-threaded build: results are never recycled")


def test_a_dropped_result_is_reused_and_a_held_one_is_not():
    pool = ResultPool(min_bytes=0)
    a = pool.empty((3, 4))
    address = a.ctypes.data
    b = pool.empty((3, 4))
    assert b.ctypes.data != address  # a is held
    del a
    c = pool.empty((3, 4))
    assert c.ctypes.data == address  # a was dropped: its memory again
    assert pool.empty((3, 4)).ctypes.data not in (address, b.ctypes.data)  # b and c held: a third


@pytest.mark.parametrize(
    "hold", [lambda a: a[1:], lambda a: memoryview(a), lambda a: a.ctypes.data_as(np.ctypeslib.ctypes.c_void_p)]
)
def test_anything_derived_from_a_result_keeps_it(hold):
    pool = ResultPool(min_bytes=0)
    a = pool.empty((4, 4))
    address = a.ctypes.data
    kept = hold(a)
    del a
    assert pool.empty((4, 4)).ctypes.data != address
    del kept


def test_other_shapes_small_results_and_the_bound():
    pool = ResultPool(min_bytes=0)
    a = pool.empty((2, 3))
    address = a.ctypes.data
    del a
    assert pool.empty((3, 2)).ctypes.data != address  # same size, other shape: not reused
    assert len(pool) == 2
    pool.empty((5,))
    assert len(pool) == 2  # at most KEEP kept
    small = ResultPool()
    small.empty((MIN_BYTES // 16,))
    assert len(small) == 0  # below MIN_BYTES: plain np.empty
    pool.release()
    assert len(pool) == 0


def _batch(samples: int, seed: int):
    mech = chain(100, 3)
    mo = smooth_random_motion(mech, np.linspace(0.0, 2.0, samples), seed=seed)
    return mech, mo.q, mo.qd, mo.qdd


@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
def test_a_loop_keeps_every_result_it_holds(method):
    """``taus.append(model.inverse_dynamics(...))`` over different batches: every kept result stays
    what its own call computed (into ``out=``, which the pool never touches), and a loop that drops
    them alternates between two."""
    samples = MIN_BYTES // (8 * 300) + 1  # just above MIN_BYTES: recycled
    mech, q, qd, qdd = _batch(samples, 1)
    model = prepare(mech, method)
    batches = [(q, qd, qdd), (q[::-1].copy(), qd, qdd), (q, qd[::-1].copy(), qdd)]
    taus = [model.inverse_dynamics(*b, check=False) for b in batches]
    for b, tau in zip(batches, taus, strict=True):
        expected = np.empty_like(q)
        model.inverse_dynamics(*b, check=False, out=expected)
        assert np.array_equal(tau, expected)
    assert len({t.ctypes.data for t in taus}) == 3
    del taus
    seen = set()
    tau = None
    for b in batches * 2:
        tau = model.inverse_dynamics(*b, check=True)
        seen.add(tau.ctypes.data)
    assert len(seen) == 2


def test_threads_sharing_a_model_get_their_own_results():
    samples = MIN_BYTES // (8 * 300) + 1
    mech, q, qd, qdd = _batch(samples, 2)
    model = prepare(mech, "newton-euler")
    inputs = [q * (1.0 + 0.01 * k) for k in range(4)]
    expected = [model.inverse_dynamics(x, qd, qdd, check=False).copy() for x in inputs]
    got: list = [None] * 4
    barrier = threading.Barrier(4)

    def work(k):
        barrier.wait()
        for _ in range(3):
            got[k] = model.inverse_dynamics(inputs[k], qd, qdd, check=False)

    run_in_threads(work, 4)
    for k in range(4):
        assert np.array_equal(got[k], expected[k])
