"""The batched inverse dynamics of ``newton-euler (numba)`` that vectorises across samples
(models/newton_euler/simd.py) against the numpy reference (models/newton_euler/passes.py).

**Error model**: that of tests/conftest.py (``K eps term_scale``), as for the per-sample kernel: the
SIMD kernel does the per-sample kernel's operations in the same order (the same element functions),
except that its sines and cosines come from models/machine/fast_trig.py (within fast_trig.ULPS, 2 ulp, of libm's); the numpy
reference takes numpy's. Where an angle falls back to libm (beyond ``fast_trig.RANGE``) the SIMD
kernel equals the per-sample kernel to the bit.

Batch sizes: around :data:`simd.MIN_SAMPLES` (below it, and for 1-D single samples, the per-sample
kernel runs, which the tests check by name), around the block (``LANES`` samples: partial blocks),
and around the size where the batch is split over threads; 2D and 3D seeded random trees with
several roots and signs -1, vertical rods and zero lengths (where inverse dynamics stays defined).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import assert_forces_agree
from test_newton_euler import TREES  # seeded random trees with several roots and signs -1, 2D and 3D

from exo_bench import prepare
from exo_bench.models.machine import fast_trig
from exo_bench.models.gait.motion import random_states
from exo_bench.models.newton_euler import simd
from exo_bench.models.mechanism.presets import exo5, random_tree
from exo_bench.models.machine.simd_blocks import LANES, parallel_min_samples, run

T, L = simd.MIN_SAMPLES, LANES
SIZES = tuple(sorted({S for S in (1, 2, 7, 8, 9, T - 1, T, T + 1, L - 1, L, L + 1, 2 * L + 5, 3 * L + 17) if S >= 1}))


def _spy(model):
    """Count the calls of the model's batch kernel (run() calls it from Python)."""
    calls = []
    kernel = model.batch_kernel

    def counted(p, q, qd, qdd, o, start, stop, *scratch):
        calls.append(stop - start)
        return kernel(p, q, qd, qdd, o, start, stop, *scratch)

    model.batch_kernel = counted
    return calls


@pytest.mark.parametrize("n,dim,seed", TREES)
def test_batches_around_every_threshold_agree_with_the_numpy_reference(n, dim, seed):
    m = random_tree(n, dim, seed)
    fast, ref = prepare(m, "newton-euler"), prepare(m, "newton-euler", kernel="numpy")
    assert fast.batch_kernel is simd.simd_inverse  # what runs, by name
    calls = _spy(fast)
    for k, S in enumerate(SIZES):
        q, qd, qdd = random_states(m, S, seed + 100 * k)
        want = ref.inverse_dynamics(q, qd, qdd)
        del calls[:]
        for check in (True, False):
            assert_forces_agree(
                fast.inverse_dynamics(q, qd, qdd, check=check), want, m, q, qd, qdd, what=f"S={S} check={check}"
            )
        out = np.full(q.shape, np.nan)
        assert fast.inverse_dynamics(q, qd, qdd, check=False, out=out) is out
        assert_forces_agree(out, want, m, q, qd, qdd, what=f"S={S} out=")
        assert (sum(calls) == 3 * S) if S >= T else not calls, f"S={S}: SIMD kernel ran for {calls}"


@pytest.mark.parametrize("dim", [2, 3])
def test_bias_forces_take_the_batch_path_too(dim):
    m = random_tree(7, dim, 4)
    q, qd, _ = random_states(m, 2 * L + 1, 4)
    fast, ref = prepare(m, "newton-euler"), prepare(m, "newton-euler", kernel="numpy")
    calls = _spy(fast)
    assert_forces_agree(fast.bias_forces(q, qd), ref.bias_forces(q, qd), m, q, qd, None)
    assert sum(calls) == 2 * L + 1


@pytest.mark.parametrize("dim", [2, 3])
def test_vertical_rods_and_zero_lengths(dim):
    """Inverse dynamics is defined at the forward chart's singular configurations: rods exactly
    vertical (3D, psi = +-pi/2) and of length zero, mixed with regular samples in one block."""
    m = exo5(dim)
    n, S = m.nlinks, L + 3
    q, qd, qdd = random_states(m, S, 9)
    q[::3, -n:][:, [0, 2]] = 0.0  # zero lengths
    if dim == 3:
        q[1::3, n : 2 * n] = np.pi / 2  # every rod vertical
        q[2::3, n + 1] = -np.pi / 2
    want = prepare(m, "newton-euler", kernel="numpy").inverse_dynamics(q, qd, qdd)
    got = prepare(m, "newton-euler").inverse_dynamics(q, qd, qdd)
    assert np.isfinite(got).all()
    assert_forces_agree(got, want, m, q, qd, qdd)
    assert_forces_agree(got, prepare(m, "pinocchio").inverse_dynamics(q, qd, qdd), m, q, qd, qdd, what="pinocchio")


@pytest.mark.parametrize("dim", [2, 3])
def test_angles_beyond_the_fast_range_take_libm_and_nan_stays_in_its_sample(dim):
    m = random_tree(8, dim, 5 if dim == 3 else 2)
    model = prepare(m, "newton-euler")
    S = 2 * L + 3
    q, qd, qdd = random_states(m, S, 8)
    angles = (dim - 1) * m.nlinks
    far = [0, L - 1, L, 2 * L + 2]
    rng = np.random.default_rng(1)
    q[np.ix_(far, range(angles))] = (
        rng.choice([-1.0, 1.0], (4, angles))
        * rng.uniform(1.0, 100.0, (4, angles))
        * np.array([fast_trig.RANGE, 10.0 * fast_trig.RANGE, 1e7, 1e15])[:, None]
    )
    q[3, 0] = 3 * fast_trig.RANGE  # one far angle among fast ones
    got = model.inverse_dynamics(q, qd, qdd, check=False)
    per_sample = np.empty(q.size)
    model.serial_kernel(*model.kernel_args, q.ravel(), qd.ravel(), qdd.ravel(), per_sample)
    assert np.array_equal(got[far], per_sample.reshape(q.shape)[far])
    want = prepare(m, "newton-euler", kernel="numpy").inverse_dynamics(q, qd, qdd)
    assert_forces_agree(got, want, m, q, qd, qdd, what="with far angles")
    q[5, 1] = np.nan
    got = model.inverse_dynamics(q, qd, qdd, check=False)
    assert np.isnan(got[5]).any() and np.isfinite(np.delete(got, 5, axis=0)).all()


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("dim", [2, 3])
def test_every_thread_count_gives_the_serial_result_to_the_bit(dim, threads):
    m = random_tree(9, dim, 12 if dim == 3 else 11)
    model = prepare(m, "newton-euler")
    P = parallel_min_samples(m.dof)  # the fewest samples run() splits
    for S in (P - 1, P, P + 2 * L + 7):
        q, qd, qdd = random_states(m, S, S)
        one, many = np.empty(q.shape), np.full(q.shape, np.nan)
        run(model.batch_kernel, model.batch_args, q.ravel(), qd.ravel(), qdd.ravel(), one.ravel(), S, threads=1)
        run(model.batch_kernel, model.batch_args, q.ravel(), qd.ravel(), qdd.ravel(), many.ravel(), S, threads=threads)
        assert np.array_equal(one, many), f"{threads} threads, S={S}"


@pytest.mark.parametrize("dim", [2, 3])
def test_the_counted_flops_are_the_kernel_s_and_grow_linearly(dim):
    """bench/perf/roofline.py runs the kernel's own steps on counting numbers: its forces
    equal the compiled kernel's to the bit (the same operations), and the count grows by the same
    number of flops per added link (O(n) per sample)."""
    from exo_bench.bench.perf.roofline import count_newton_euler_simd
    from exo_bench.models.mechanism.presets import chain

    flops = []
    for n in (10, 20, 40):
        m = chain(n, dim)
        q, qd, qdd = random_states(m, T, n)
        count, tau = count_newton_euler_simd(m, q[0], qd[0], qdd[0])
        assert np.array_equal(tau, prepare(m, "newton-euler").inverse_dynamics(q, qd, qdd)[0]), n
        flops.append(count["flops"])
    assert flops[2] - flops[1] == 2 * (flops[1] - flops[0]) > 0, flops


def test_the_block_size_changes_at_narrow_from_links():
    """The batched kernel has blocks of :data:`LANES` samples below :data:`simd.NARROW_FROM_LINKS` links
    and of :data:`simd.NARROW_LANES` from it on (what a prepared model of that size runs: the
    tests below, by name)."""
    n = simd.NARROW_FROM_LINKS
    assert simd.NARROW_LANES < LANES
    assert simd.kernel_for(n - 1) is simd.simd_inverse is simd.blocks_for(n - 1).simd_inverse
    assert simd.kernel_for(n) is simd._NARROW.simd_inverse is simd.blocks_for(n).simd_inverse


#: The narrow blocks on small trees: :data:`simd.NARROW_FROM_LINKS` moved down to this many links (the
#: kernel and its scratch depend on the links only through their count; the block boundary is what is
#: tested). The real sizes, n = 799 and 800 (a minute and a half), are marked slow.
SMALL_NARROW_FROM = 12


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("n", [SMALL_NARROW_FROM - 1, SMALL_NARROW_FROM])
def test_the_narrow_blocks_agree_with_the_numpy_reference_around_the_boundary(n, dim, monkeypatch):
    """As the test below, with the boundary at :data:`SMALL_NARROW_FROM` links."""
    monkeypatch.setattr(simd, "NARROW_FROM_LINKS", SMALL_NARROW_FROM)
    _narrow_blocks_agree(n, dim)


@pytest.mark.slow
@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("n", [simd.NARROW_FROM_LINKS - 1, simd.NARROW_FROM_LINKS])
def test_large_mechanisms_run_the_narrow_blocks_and_agree_with_the_numpy_reference(n, dim):
    """Around :data:`simd.NARROW_FROM_LINKS` the block size changes (:data:`simd.NARROW_LANES` samples
    from it on): batch sizes that are not multiples of either block (partial blocks), against the
    numpy reference in the error model, and to the bit against the other block size (the same
    operations per sample, so a batch's result does not depend on how it is blocked). Slow: the
    test above runs the same at 11 and 12 links with the boundary moved there."""
    _narrow_blocks_agree(n, dim)


def _narrow_blocks_agree(n: int, dim: int) -> None:
    m = random_tree(n, dim, 7)
    fast, ref = prepare(m, "newton-euler"), prepare(m, "newton-euler", kernel="numpy")
    narrow = n >= simd.NARROW_FROM_LINKS
    kernel = simd.kernel_for(n)
    assert fast.batch_kernel is kernel  # what runs, by name
    assert (kernel is simd._NARROW.simd_inverse) == narrow and (kernel is simd.simd_inverse) != narrow
    other = simd.simd_inverse if narrow else simd._NARROW.simd_inverse
    calls = _spy(fast)
    for S in (1, simd.NARROW_LANES - 1, simd.NARROW_LANES + 1, LANES + 5):
        q, qd, qdd = random_states(m, S, n + S)
        del calls[:]
        got = fast.inverse_dynamics(q, qd, qdd)
        assert sum(calls) == S, f"S={S}: batch kernel ran for {calls}"
        assert_forces_agree(got, ref.inverse_dynamics(q, qd, qdd), m, q, qd, qdd, what=f"n={n} S={S}")
        o = np.full(q.shape, np.nan)
        other(fast.batch_args, q.reshape(-1), qd.reshape(-1), qdd.reshape(-1), o.reshape(-1), 0, S)
        np.testing.assert_array_equal(got, o)
    assert simd._NARROW.simd_inverse.signatures  # the narrow variant was compiled and ran
