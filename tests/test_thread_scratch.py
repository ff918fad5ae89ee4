"""The SIMD kernels' scratch kept per thread (models/machine/simd_blocks.ThreadScratch): each thread reuses its
own, and the forces are the same bits as with a scratch allocated per call, whatever ran in that
scratch before (a bigger or smaller batch, another thread count, the other mechanism's model)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from conftest import smooth_states
from exo_bench import prepare
from exo_bench.models.machine import simd_blocks
from exo_bench.models.mechanism.presets import chain, exo5, random_tree


@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
@pytest.mark.parametrize(
    "mech", [exo5(3), exo5(2), random_tree(30, 3, 5), random_tree(30, 2, 6), chain(800, 3)], ids=lambda m: m.name
)
def test_a_reused_scratch_gives_the_bits_of_a_fresh_one(method, mech):
    model = prepare(mech, method)
    p = model.batch_args if method == "newton-euler" else model.kernel_args[0]
    for samples, threads, seed in ((77, 2, 1), (5, 1, 2), (300, 2, 3), (33, 1, 4)):
        q, qd, qdd = smooth_states(mech, samples, seed)
        fresh, kept = np.empty_like(q), np.empty_like(q)
        flat = (q.reshape(-1), qd.reshape(-1), qdd.reshape(-1))
        simd_blocks.run(model.batch_kernel, p, *flat, fresh.reshape(-1), samples, threads=1)
        simd_blocks.run(
            model.batch_kernel, p, *flat, kept.reshape(-1), samples, threads=threads, scratch=model.batch_scratch
        )
        assert np.array_equal(kept, fresh), (samples, threads)
        assert np.array_equal(model.inverse_dynamics(q, qd, qdd, check=False), fresh)


def test_each_thread_keeps_its_own_scratch():
    made = []

    def make(n, blocks):
        made.append(threading.get_ident())
        return (np.zeros(n), np.zeros(blocks), np.zeros(1))

    scratch = simd_blocks.ThreadScratch(make, 4, 3)
    here = scratch()
    assert scratch() is here and made == [threading.get_ident()]
    other = []
    t = threading.Thread(target=lambda: other.extend([scratch(), scratch()]))
    t.start()
    t.join()
    assert other[0] is other[1] and other[0] is not here and len(made) == 2
