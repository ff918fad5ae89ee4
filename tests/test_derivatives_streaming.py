"""The streamed output of the inverse-dynamics derivatives (models/newton_euler/derivatives_compiled.py):
large batches write their rows by non-temporal stores, from a scratch row computed by the same
operations, so the streamed output is bit-identical to the ordinary one (the 50-digit agreement of
tests/test_reference_to_n100.py and tests/test_derivatives_analytic.py then carries over), in 2D and
3D, on trees with branch signs, serial and over threads, at every row length the vector blocks meet
(a multiple of 4, and 2 more). And the decision to stream: only outputs over the caches, rows 16-byte
aligned (the stores declare it), compiled kernels."""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.models.mechanism import presets
from exo_bench.models.gait.motion import random_states
from exo_bench.models.newton_euler import derivatives_compiled as dc
from exo_bench.models.newton_euler import derivatives_compiled as ds
from exo_bench.models.newton_euler.derivatives import prepare_inverse_derivatives

CASES = [
    pytest.param(lambda: presets.random_tree(6, 3, seed=11), id="tree6-3d"),  # dof 18: blocks of 4 and a 2
    pytest.param(lambda: presets.random_tree(8, 3, seed=12), id="tree8-3d"),  # dof 24: blocks of 4 only
    pytest.param(lambda: presets.random_tree(7, 2, seed=13), id="tree7-2d"),  # dof 14: 4s and a 2, 2D rows
    pytest.param(lambda: presets.chain(12, 3), id="chain12-3d"),
]


def _aligned(shape) -> np.ndarray:
    """An uninitialised float64 array of ``shape`` whose data starts 64-byte aligned."""
    size = int(np.prod(shape))
    buf = np.empty(size + 8)
    off = (-buf.ctypes.data % 64) // 8
    return buf[off : off + size].reshape(shape)


@pytest.mark.parametrize("make", CASES)
@pytest.mark.parametrize("driver", ["serial", "parallel"])
def test_streamed_rows_are_bit_identical_to_ordinary_stores(make, driver):
    mech = make()
    d = prepare_inverse_derivatives(mech)
    q, qd, qdd = random_states(mech, 9, seed=mech.nlinks)
    shape = (9, mech.dof, mech.dof)
    plain = tuple(np.full(shape, np.nan) for _ in range(3))
    streamed = tuple(_aligned(shape) for _ in range(3))
    for o in streamed:
        o.fill(np.nan)  # a row the streamed path missed stays NaN
    kernel = dc.derivatives_serial if driver == "serial" else dc.derivatives_parallel
    kernel(d.table, d.mu, d.g, d.dim, q, qd, qdd, *plain, False)
    kernel(d.table, d.mu, d.g, d.dim, q, qd, qdd, *streamed, True)
    for name, a, b in zip(("dtau_dq", "dtau_dqd", "M"), plain, streamed):
        assert np.isfinite(b).all(), f"{name}: entries the streamed rows did not write"
        np.testing.assert_array_equal(b, a, err_msg=name)


def test_a_large_batch_streams_through_the_public_call():
    """Over STREAM_MIN_BYTES of output the public call streams (the kernel's flag, asked of
    :func:`streams`), and gives the bits of the ordinary stores."""
    mech = presets.chain(20, 3)  # dof 60: 86 kB of output per sample
    samples = ds.STREAM_MIN_BYTES // (3 * 8 * mech.dof**2) + 1
    q, qd, qdd = random_states(mech, samples, seed=3)
    d = prepare_inverse_derivatives(mech)
    got = d(q, qd, qdd, kernel="numba")
    assert ds.streams(got, mech.dof)
    plain = tuple(np.empty_like(g) for g in got)
    dc.derivatives_serial(d.table, d.mu, d.g, d.dim, q, qd, qdd, *plain, False)
    for a, b in zip(got, plain):
        np.testing.assert_array_equal(a, b)


def test_only_large_aligned_outputs_with_even_rows_stream():
    big = ds.STREAM_MIN_BYTES // 8 // 3 + 64  # float64 entries per output: three are over the threshold
    dof = 64
    rows = big // dof + 1
    aligned = tuple(_aligned((rows, dof)) for _ in range(3))
    assert ds.streams(aligned, dof)
    assert not ds.streams(tuple(o[:2] for o in aligned), dof)  # a small output stays in cache
    shifted = tuple(_aligned((rows * dof + 1,))[1:].reshape(rows, dof) for _ in range(3))  # 8 bytes off 16
    assert not ds.streams(shifted, dof)
    odd = tuple(_aligned((rows, dof - 1)) for _ in range(3))  # odd rows: every other row starts 8 bytes off
    assert not ds.streams(odd, dof - 1)
