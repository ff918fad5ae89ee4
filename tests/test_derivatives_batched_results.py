"""Batched derivative calls without ``out=`` (models/newton_euler/derivatives.py, models/derivatives.py): the
results of a loop that drops them are recycled, so a call pays for its arithmetic, not for new pages.

A ``(S, dof, dof)`` result of 128 KiB or more is served by glibc from a fresh mapping whenever its heap has
nothing free of that size (its threshold starts at 128 KiB), and the OS zeroes each page on first touch
in the kernel's time: exo5-3d, 256 samples (three results of 460 kB), one call measured 3.6 us per sample
with 193 page faults per call against 1.6 us into preallocated ``out`` in the same process (load ~1.8).
Whether glibc maps afresh depends on what the process allocated before; the pool makes it not matter.
Counted, not timed: the pool's kept results and the process's minor page faults (``getrusage``).
"""

from __future__ import annotations

import resource

import numpy as np

from exo_bench.api import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5
from exo_bench.models.runtime.prepared import RECYCLES

SAMPLES = 256  # three (256, 15, 15) results of 460 kB each: over 128 KiB, under result_pool's 4 MiB


def _faults() -> int:
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def _pages(arrays) -> int:
    return sum(a.nbytes for a in arrays) // 4096


def test_inverse_derivative_results_are_recycled_in_a_loop():
    mech = exo5(3)
    d = prepare(mech, "newton-euler").derivatives.inverse_derivatives
    q, qd, qdd = random_states(mech, SAMPLES, seed=3)
    first = d(q, qd, qdd)
    pages = _pages(first)
    addresses = {a.ctypes.data for a in first}
    del first
    before = _faults()
    for _ in range(10):
        res = d(q, qd, qdd)
        assert not (RECYCLES and {a.ctypes.data for a in res} - addresses), "a new result, not a dropped one"
        del res
    assert _faults() - before < pages, f"{_faults() - before} page faults in 10 calls: new pages per call"


def test_forward_derivative_results_are_recycled_in_a_loop():
    mech = exo5(3)
    d = prepare(mech, "newton-euler").derivatives
    q, qd, qdd = random_states(mech, SAMPLES, seed=4)
    tau = prepare(mech, "newton-euler").inverse_dynamics(q, qd, qdd, check=False)
    first = d.forward_dynamics(q, qd, tau, check=False)
    addresses = {a.ctypes.data for a in first[1:]}
    pages = _pages(first[1:])
    del first
    before = _faults()
    for _ in range(10):
        res = d.forward_dynamics(q, qd, tau, check=False)
        assert not (RECYCLES and {a.ctypes.data for a in res[1:]} - addresses), "a new result, not a dropped one"
        del res
    assert _faults() - before < pages, f"{_faults() - before} page faults in 10 calls: new pages per call"


def test_a_result_still_held_is_never_handed_out_again():
    mech = exo5(3)
    d = prepare(mech, "newton-euler").derivatives.inverse_derivatives
    q, qd, qdd = random_states(mech, SAMPLES, seed=5)
    held = d(q, qd, qdd)
    kept = tuple(a.copy() for a in held)
    for _ in range(3):
        other = d(q + 0.1, qd, qdd)
        assert not any(np.may_share_memory(a, b) for a in held for b in other)
    assert all(np.array_equal(a, b) for a, b in zip(held, kept))
