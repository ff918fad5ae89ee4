"""The one-sample calls allocate nothing in numba per call (issue 35): their compiled entries
(matrix_method/numba_kernels/lean.py, models/newton_euler/compiled.py) take their kernels' scratch on the
stack of the call (:func:`exo_bench.models.states.validation_pass.stack_matrix`) and are compiled without numba's
reference-counted runtime, so a call makes no NRT allocation. Counted, not timed: numba's own allocation
counters (``memsys_enable_stats``) over calls of every form.

Before, matrix-factored's kernel made a ``(7, n)`` array and newton-euler's a zeroed ``(n, 16)`` one on
every call: about 90 ns of a 0.3 us call on exo5-3d. The scratch is the call's own, so threads calling
one model get the same numbers as one thread."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5

#: (method, kernel option or None, dimension): every lean one-sample call.
CALLS = [("matrix-factored", 2), ("matrix-factored", 3), ("newton-euler", 2), ("newton-euler", 3)]


@pytest.fixture(scope="module", params=CALLS, ids=lambda c: f"{c[0]}-{c[1]}d")
def case(request):
    method, dim = request.param
    mech = exo5(dim)
    model = prepare(mech, method)
    assert model._entries.inverse_fast is not None
    q, qd, qdd = (np.ascontiguousarray(a) for a in random_states(mech, 4, seed=7))
    one = model._entries.inverse_one  # the per-sample kernel: the same arithmetic, bit for bit
    want = np.array([one(*(np.ascontiguousarray(a[s]) for a in (q, qd, qdd)), np.empty(mech.dof)) for s in range(4)])
    return model, (q, qd, qdd), want


def _nrt_allocations(fn) -> int:
    """NRT allocations made while ``fn()`` runs (numba's counters, enabled for the call only)."""
    from numba.core.runtime import _nrt_python as nrt
    from numba.core.runtime import rtsys

    enabled = nrt.memsys_stats_enabled()
    nrt.memsys_enable_stats()
    try:
        before = rtsys.get_allocation_stats()
        fn()
        after = rtsys.get_allocation_stats()
    finally:
        if not enabled:
            nrt.memsys_disable_stats()
    return (after.alloc - before.alloc) + (after.mi_alloc - before.mi_alloc)


def test_a_one_sample_call_allocates_nothing_in_numba(case):
    model, (q, qd, qdd), want = case
    one = [np.ascontiguousarray(a[0]) for a in (q, qd, qdd)]
    out = np.empty(model.dof)

    def calls():
        for _ in range(5):
            model.inverse_dynamics(*one, check=False, out=out)
            model.inverse_dynamics(*one, check=False)
            model.inverse_dynamics(*one)

    calls()  # first use: compiles or loads the entries
    assert _nrt_allocations(calls) == 0
    np.testing.assert_array_equal(model.inverse_dynamics(*one, check=False), want[0])


def test_the_counter_sees_an_allocation_in_compiled_code():
    """The oracle can fail: an ``np.empty`` in compiled code is counted (with the scratch from
    ``np.empty``, the one-sample calls counted 2 per call: 30 over the 15 calls above)."""
    import numba

    empty = numba.njit(lambda n: np.empty(n).size)
    empty(3)
    assert _nrt_allocations(lambda: empty(3)) > 0


def test_threads_calling_one_model_get_the_one_thread_numbers(case):
    model, (q, qd, qdd), want = case
    got: dict[int, list] = {}

    def run(k: int) -> None:
        s = k % q.shape[0]
        one = [np.ascontiguousarray(a[s]) for a in (q, qd, qdd)]
        got[k] = [model.inverse_dynamics(*one, check=False) for _ in range(300)]

    threads = [threading.Thread(target=run, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k, results in got.items():
        for r in results:
            np.testing.assert_array_equal(r, want[k % q.shape[0]])
