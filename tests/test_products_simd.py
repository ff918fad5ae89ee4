"""The directional derivatives across SIMD lanes (models/newton_euler/products_simd.py, issue 36): the JVP and
VJP of inverse dynamics in blocks of samples, against the numpy reference of the same formulas
(models/newton_euler/products.py, which tests/test_jvp.py holds to the full Jacobians for every kernel).

**Error model.** The two evaluate the same per-rod products and passes; their sines and cosines differ by
an ulp or two (the batched kernel's branch-free ``sin``/``cos``, models/machine/fast_trig.py) and their sums run in
other orders, so they differ by the rounding of the Jacobian's entries times the direction, the bound of
tests/test_jvp.py: ``K eps sum_j D_ij |v_j|`` with ``D`` the scale of each entry's differentiated terms
(tests/test_derivatives_analytic.py's ``derivative_scales``, conftest's ``mass_matrix_scale``)."""

from __future__ import annotations

import numpy as np
import pytest
from test_derivatives_analytic import derivative_scales, states
from test_jvp import _directions, _mv, _vm

from conftest import assert_close, mass_matrix_scale
from exo_bench import presets
from exo_bench.models.derivatives import Derivatives
from exo_bench.models.derivatives import PRODUCTS_SIMD_BELOW_LINKS
from exo_bench.models.newton_euler import products
from exo_bench.models.mechanism.presets import random_tree
from exo_bench.models.machine.simd_blocks import LANES

TREES = [random_tree(7, 2, 22), random_tree(9, 3, 23), presets.exo5(dim=3)]
#: one sample; one whole block and a partial one (not a multiple of the block width)
SAMPLES = (1, LANES + 5)


@pytest.fixture(scope="module")
def providers():
    """One provider per tree (each holds the SIMD kernel's per-thread scratch), shared by the tests."""
    return {m.name: Derivatives(m, kernel="numba", products="simd") for m in TREES}


def test_the_trees_have_branch_signs(providers):
    """The random trees hold rods of sign -1 (the kernel multiplies by them) and more than one root path."""
    for m in TREES[:2]:
        table = providers[m.name].table
        assert (table[1] < 0).any() and (table[1] > 0).any(), m.name
        assert len(set(m.parent)) > 2, m.name


@pytest.mark.parametrize("samples", SAMPLES)
@pytest.mark.parametrize("mech", TREES, ids=[m.name for m in TREES])
def test_simd_products_equal_the_numpy_reference(providers, mech, samples):
    """JVP and VJP of the SIMD kernel against the numpy reference, 2D and 3D trees with branch signs, one
    sample and a batch of one whole block and a partial one."""
    from exo_bench.models.newton_euler import products_simd as ps

    D = providers[mech.name]
    q, qd, qdd = states(mech, samples, 61)
    dq, dqd, dqdd, w = _directions(mech, samples, 62)
    g = float(mech.g)
    sq, sqd = derivative_scales(mech, q, qd, qdd)
    sm = mass_matrix_scale(mech, q)
    ref = products.inverse_jvp(D.tree, mech.dim, g, q, qd, qdd, dq, dqd, dqdd)
    got = ps.jvp(D.table, mech.dim, g, q, qd, qdd, dq, dqd, dqdd, D.products_scratch)
    scale = _mv(sq, np.abs(dq)) + _mv(sqd, np.abs(dqd)) + _mv(sm, np.abs(dqdd))
    assert_close(got, ref, scale, what=f"{mech.name} jvp")
    refs = products.inverse_vjp(D.tree, mech.dim, g, q, qd, qdd, w)
    gots = ps.vjp(D.table, mech.dim, g, q, qd, qdd, w, D.products_scratch)
    for what, a, b, s in zip(("w dtau/dq", "w dtau/dqd", "w M"), gots, refs, (sq, sqd, sm)):
        assert_close(a, b, _vm(np.abs(w), s), what=f"{mech.name} vjp {what}")


def test_the_provider_runs_the_simd_products_for_batches(providers):
    """``model.derivatives``' products run the SIMD kernel for a batch (``products="auto"``, the default),
    say so (:meth:`Derivatives.products_kernel`), and give the SIMD kernel's numbers to the bit."""
    mech = TREES[1]
    auto, simd = Derivatives(mech), providers[mech.name]
    assert auto.products_kernel == "simd"
    assert Derivatives(presets.chain(PRODUCTS_SIMD_BELOW_LINKS, 3)).products_kernel == "numba"  # the largest
    assert Derivatives(mech, kernel="numpy").products_kernel == "numpy"
    q, qd, qdd = states(mech, 9, 63)
    dq, dqd, dqdd, w = _directions(mech, 9, 64)
    np.testing.assert_array_equal(
        auto.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd), simd.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd)
    )
    for a, b in zip(auto.inverse_dynamics_vjp(q, qd, qdd, w), simd.inverse_dynamics_vjp(q, qd, qdd, w)):
        np.testing.assert_array_equal(a, b)


def test_a_batch_equals_its_samples_one_by_one(providers):
    """The result of a sample does not depend on the batch around it (where its block is cut): every row
    of a batch of 37 equals that sample alone, to the bit."""
    mech = TREES[2]
    D = providers[mech.name]
    q, qd, qdd = states(mech, LANES + 5, 65)
    dq, dqd, dqdd, w = _directions(mech, LANES + 5, 66)
    batch = D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd)
    vjp = D.inverse_dynamics_vjp(q, qd, qdd, w)
    for s in (0, 17, LANES, LANES + 4):
        np.testing.assert_array_equal(D.inverse_dynamics_jvp(q[s], qd[s], qdd[s], dq[s], dqd[s], dqdd[s]), batch[s])
        for a, b in zip(D.inverse_dynamics_vjp(q[s], qd[s], qdd[s], w[s]), vjp):
            np.testing.assert_array_equal(a, b[s])


def test_unchecked_products_take_plain_arrays_only_with_the_same_numbers(providers):
    """``check=False`` on C-contiguous float64 arrays of one shape goes straight to the kernel, with the
    numbers of ``check=True``, to the bit, batch and one sample; anything else (a Fortran-ordered view,
    float32, a list, a wrong length) is refused by the array gate (models/states/array_gate.py) naming the field:
    ``check=False`` converts nothing (``check=True`` converts it, with the same numbers)."""
    mech = TREES[0]
    D = providers[mech.name]
    q, qd, qdd = states(mech, 5, 67)
    dq, dqd, dqdd, w = _directions(mech, 5, 68)
    ref = D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd)
    refs = D.inverse_dynamics_vjp(q, qd, qdd, w)
    np.testing.assert_array_equal(D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd, check=False), ref)
    for a, b in zip(D.inverse_dynamics_vjp(q, qd, qdd, w, check=False), refs):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(
        D.inverse_dynamics_jvp(q[2], qd[2], qdd[2], dq[2], dqd[2], dqdd[2], check=False), ref[2]
    )
    fortran = np.asfortranarray(dq)
    np.testing.assert_array_equal(D.inverse_dynamics_jvp(q, qd, qdd, fortran, dqd, dqdd), ref)
    with pytest.raises(ValueError, match=r"field 'dq': expected .*float64.*not C-contiguous"):
        D.inverse_dynamics_jvp(q, qd, qdd, fortran, dqd, dqdd, check=False)
    with pytest.raises(ValueError, match=r"field 'q': expected .*float64.*float32"):
        D.inverse_dynamics_jvp(q.astype(np.float32), qd, qdd, dq, dqd, dqdd, check=False)
    with pytest.raises(ValueError, match=r"field 'q': expected .*float64.*got list"):
        D.inverse_dynamics_vjp(q.tolist(), qd, qdd, w, check=False)
    for a, b in zip(D.inverse_dynamics_vjp(q.tolist(), qd, qdd, w), refs):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"field 'w': expected shape \(samples, 14\), got \(5, 4\)"):
        D.inverse_dynamics_vjp(q, qd, qdd, w[:, :4], check=False)


def test_unchecked_products_estimate_their_memory_first(providers, monkeypatch):
    """``check=False`` refuses a batch over the usable memory before any work (CallTooLarge), as ``check=True``
    does (tests/test_call_memory_estimate.py holds that path on broadcast views)."""
    from exo_bench.models.machine import memory

    mech = TREES[0]
    D = providers[mech.name]
    monkeypatch.setattr(memory, "usable_memory", lambda: 2**20)
    q = np.zeros((200_000, mech.dof))  # 200,000 x 14 x 512 bytes of work: 1.4 GB estimated
    with pytest.raises(memory.CallTooLarge, match="200000 samples of 14 coordinates"):
        D.inverse_dynamics_jvp(q, q, q, q, q, q, check=False)
    with pytest.raises(memory.CallTooLarge, match="inverse-dynamics VJP"):
        D.inverse_dynamics_vjp(q, q, q, q, check=False)


def test_the_kernel_cache_is_keyed_on_every_file_it_inlines():
    """numba's on-disk cache of each compiled function of products_simd.py is keyed (models/machine/numba_cache.py)
    on the files whose code it compiles in: its own, the elements' derivatives, the rod elements,
    newton-euler's batched passes, the branch-free sin/cos and the block layout. An edit to any of them
    recompiles it (tests/test_kernel_cache.py edits rod_elements.py in a copy of the package and sees it)."""
    from pathlib import Path

    from numba.core.registry import CPUDispatcher

    from exo_bench.models.machine import fast_trig, numba_cache, simd_blocks
    from exo_bench.models.mechanism import rod_elements
    from exo_bench.models.newton_euler import derivative_elements, products_simd, simd

    kernels = [
        f
        for f in vars(products_simd).values()
        if isinstance(f, CPUDispatcher) and f.__module__ == products_simd.__name__
    ]
    assert {"simd_jvp", "simd_vjp", "jvp_whole", "vjp_whole", "_jvp_rods", "_vjp_out"} <= {f.__name__ for f in kernels}
    wanted = {
        Path(m.__file__).resolve()
        for m in (products_simd, derivative_elements, rod_elements, simd, fast_trig, simd_blocks)
    }
    for f in kernels:
        locator = f._cache._impl.locator
        assert isinstance(locator, numba_cache.KernelSourceLocator), f.__name__
        assert wanted <= set(numba_cache.inlined_sources(locator._kernel_dir)), f.__name__


def test_a_batch_split_over_threads_gives_the_same_bits(providers, monkeypatch):
    """A batch large enough to be split over threads (simd_blocks.run, shares of whole blocks) gives the
    numbers of the calling thread alone, to the bit: the threshold is lowered so that 100 samples split."""
    import numba

    from exo_bench.models.machine import simd_blocks
    from exo_bench.models.newton_euler import products_simd as ps

    mech = TREES[1]
    D = providers[mech.name]
    q, qd, qdd = states(mech, 100, 69)
    dq, dqd, dqdd, w = _directions(mech, 100, 70)
    args = (D.table, mech.dim, float(mech.g), q, qd, qdd)
    alone = ps.jvp(*args, dq, dqd, dqdd, D.products_scratch), ps.vjp(*args, w, D.products_scratch)
    monkeypatch.setattr(simd_blocks, "PARALLEL_MIN_ELEMENTS", 1)
    calls = []
    run = simd_blocks.run
    monkeypatch.setattr(ps, "run", lambda *a, **k: calls.append(run(*a, threads=2, **k)))
    assert numba.config.NUMBA_NUM_THREADS >= 1
    split = ps.jvp(*args, dq, dqd, dqdd, D.products_scratch), ps.vjp(*args, w, D.products_scratch)
    assert len(calls) == 2
    np.testing.assert_array_equal(split[0], alone[0])
    for a, b in zip(split[1], alone[1]):
        np.testing.assert_array_equal(a, b)


def test_angles_beyond_the_fast_range_and_nan_states(providers):
    """Angles beyond the branch-free sin/cos's range (models/machine/fast_trig.py's RANGE) are redone with libm by
    newton-euler's forward pass, so the products still equal the numpy reference to the error model; a NaN
    state (check=False) gives NaN in its own sample and nowhere else: never hidden, never spread."""
    from exo_bench.models.machine.fast_trig import RANGE

    mech = TREES[1]
    D = providers[mech.name]
    q, qd, qdd = states(mech, LANES + 5, 71)
    q[::3, 0] += 2e3 * np.pi
    q[5, 1] = 1.5 * RANGE
    dq, dqd, dqdd, _ = _directions(mech, LANES + 5, 72)
    sq, sqd = derivative_scales(mech, q, qd, qdd)
    scale = _mv(sq, np.abs(dq)) + _mv(sqd, np.abs(dqd)) + _mv(mass_matrix_scale(mech, q), np.abs(dqdd))
    ref = products.inverse_jvp(D.tree, mech.dim, float(mech.g), q, qd, qdd, dq, dqd, dqdd)
    assert_close(D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd, check=False), ref, scale, what="beyond RANGE")
    q[7, 2] = np.nan
    got = D.inverse_dynamics_jvp(q, qd, qdd, dq, dqd, dqdd, check=False)
    assert np.isnan(got[7]).any() and np.isfinite(np.delete(got, 7, axis=0)).all()
    vjp = D.inverse_dynamics_vjp(q, qd, qdd, dq, check=False)
    assert all(np.isnan(x[7]).any() and np.isfinite(np.delete(x, 7, axis=0)).all() for x in vjp)
