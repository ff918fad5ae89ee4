"""The batched kernel that vectorises across samples (matrix_method/numba_kernels/simd.py) and the lean
one-sample entry (matrix_method/numba_kernels/lean.py) of ``matrix-factored (numba)``.

**Error model** (that of tests/test_compiled.py): the SIMD kernel does the per-sample kernel's
operations in the same order, except that its sines and cosines come from
models/machine/fast_trig.py (within fast_trig.ULPS, 2 ulp, of libm's); the numpy reference takes them from
``tan(x/2)`` (a few 1e-16 absolute) and sums ``c @ kappa`` in BLAS's order. Every force is a sum of
O(dof) terms of at most a few ``max|tau|``, so the kernels differ by at most ``k * eps * dof *
max|tau|``, below ``1e-14 * max|tau|`` for ``dof <= 24``: the bound asserted. Against the per-sample
compiled kernel the same bound holds (only the trig differs), and where the SIMD kernel falls back
to libm (angles beyond ``fast_trig.RANGE``) the two are identical to the bit.

Batch sizes: around the block (``LANES`` samples: a partial block, one, one more), around the
threshold where :func:`exo_bench.models.machine.simd_blocks.run` splits a batch over threads, with 1, 2 and 3 threads
(uneven shares); 2D and 3D, chains and random trees with negative signs.
"""

from __future__ import annotations

import numpy as np
import pytest

from conftest import uniform_states
from exo_bench import prepare
from exo_bench.matrix_method.numba_kernels import simd as compiled_simd
from exo_bench.models.machine import fast_trig
from exo_bench.models.mechanism.presets import chain, exo5, random_tree
from exo_bench.models.machine import simd_blocks
from exo_bench.models.machine.simd_blocks import parallel_min_samples, run

TOL = 1e-14
MECHS = [chain(1, 2), random_tree(6, 2, seed=0), chain(1, 3), chain(4, 3), random_tree(8, 3, seed=1), exo5(3)]
L = compiled_simd.LANES


def _sizes(mech):
    """Around the block and around the fewest samples that run() splits over threads."""
    P = parallel_min_samples(mech.dof)
    return tuple(sorted({1, L - 1, L, L + 1, 2 * L + 5, P - 1, P, P + L + 3} - {0}))


def _close(got, want, what):
    scale = np.abs(want).max()
    err = np.abs(got - want).max()
    assert np.isfinite(got).all(), what
    assert err <= TOL * scale, f"{what}: {err / scale:.2e} relative"


@pytest.mark.parametrize("mech", MECHS, ids=lambda m: m.name)
def test_simd_batches_equal_the_numpy_reference(mech):
    fast, ref = prepare(mech, "matrix-factored"), prepare(mech, "matrix-factored", kernel="numpy")
    assert fast.batch_kernel is compiled_simd.KERNELS[mech.dim]  # what runs, by name
    for k, S in enumerate(_sizes(mech)):
        q, qd, qdd = uniform_states(mech, S, seed=k)
        want = ref.inverse_dynamics(q, qd, qdd)
        for check in (True, False):
            _close(fast.inverse_dynamics(q, qd, qdd, check=check), want, f"{mech.name} S={S} check={check}")
        out = np.full(q.shape, np.nan)
        assert fast.inverse_dynamics(q, qd, qdd, check=False, out=out) is out
        _close(out, want, f"{mech.name} S={S} out=")


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("mech", [random_tree(8, 3, seed=1), random_tree(6, 2, seed=0)], ids=lambda m: m.name)
def test_every_thread_count_gives_the_serial_result_to_the_bit(mech, threads):
    """The threads take contiguous shares of whole blocks: each sample is computed by the same code
    whoever computes it, so the result equals the one-thread result exactly."""
    model = prepare(mech, "matrix-factored")
    p = model.kernel_args[0]
    P = parallel_min_samples(mech.dof)
    for S in (P - 1, P, P + 2 * L + 7):
        q, qd, qdd = uniform_states(mech, S, seed=S)
        one, many = np.empty(q.shape), np.full(q.shape, np.nan)
        run(model.batch_kernel, p, q.ravel(), qd.ravel(), qdd.ravel(), one.ravel(), S, threads=1)
        run(model.batch_kernel, p, q.ravel(), qd.ravel(), qdd.ravel(), many.ravel(), S, threads=threads)
        assert np.array_equal(one, many), f"{threads} threads, S={S}"


@pytest.mark.parametrize("mech", [exo5(3), random_tree(6, 2, seed=0)], ids=lambda m: m.name)
def test_simd_equals_the_per_sample_kernel(mech):
    model = prepare(mech, "matrix-factored")
    p = model.kernel_args[0]
    q, qd, qdd = uniform_states(mech, 3 * L + 1, seed=7)
    want = np.empty(q.size)
    model.serial_kernel(p, q.ravel(), qd.ravel(), qdd.ravel(), want)
    _close(model.inverse_dynamics(q, qd, qdd, check=False).ravel(), want, "simd vs per-sample")


@pytest.mark.parametrize("mech", [exo5(3), random_tree(6, 2, seed=0)], ids=lambda m: m.name)
def test_angles_beyond_the_fast_range_and_nan_take_libm(mech):
    """Angles beyond fast_trig.RANGE go through libm, as in the per-sample kernel: samples whose
    every angle is beyond it equal that kernel to the bit (the others agree within the error
    model); a NaN angle gives NaN forces in its sample only."""
    model = prepare(mech, "matrix-factored")
    p = model.kernel_args[0]
    q, qd, qdd = uniform_states(mech, 2 * L + 3, seed=8)
    far = [0, L - 1, L, 2 * L + 2]  # every angle of these samples beyond the range
    angles = (mech.dim - 1) * mech.nlinks
    rng = np.random.default_rng(1)
    q[np.ix_(far, range(angles))] = (
        rng.choice([-1.0, 1.0], (4, angles))
        * rng.uniform(1.0, 100.0, (4, angles))
        * np.array([fast_trig.RANGE, 10.0 * fast_trig.RANGE, 1e7, 1e15])[:, None]
    )
    q[far[2], 0] = np.nextafter(fast_trig.RANGE, np.inf)
    q[3, 0] = 3 * fast_trig.RANGE  # one far angle among fast ones
    got = model.inverse_dynamics(q, qd, qdd, check=False)
    want = np.empty(q.size)
    model.serial_kernel(p, q.ravel(), qd.ravel(), qdd.ravel(), want)
    want = want.reshape(q.shape)
    assert np.array_equal(got[far], want[far])
    _close(got, want, "with far angles")
    q[5, 0] = np.nan
    got = model.inverse_dynamics(q, qd, qdd, check=False)
    assert np.isnan(got[5]).any() and np.isfinite(np.delete(got, 5, axis=0)).all()


def test_lean_one_sample_path_equals_the_kernel_and_allocates_nothing():
    mech = exo5(3)
    model = prepare(mech, "matrix-factored")
    q, qd, qdd = (x[0].copy() for x in uniform_states(mech, 1, seed=9))
    out = np.full(mech.dof, np.nan)
    assert model.inverse_dynamics(q, qd, qdd, check=False, out=out) is out
    want = np.empty(mech.dof)
    model.serial_kernel(model.kernel_args[0], q, qd, qdd, want)
    assert np.array_equal(out, want)
    assert np.array_equal(model.inverse_dynamics(q, qd, qdd), want)  # check=True: the same forces


def test_lean_path_refuses_what_is_not_memory_safe():
    """With check=False and out=, every layout the lean entry cannot take safely falls to the
    checked path's ValueError naming the field: strided views, wrong lengths, other dtypes, 2-D
    against 1-D, read-only out; none reads or writes past an array."""
    mech = exo5(3)
    model = prepare(mech, "matrix-factored")
    d = mech.dof
    q = np.full(d, 0.3)
    good = np.empty(d)
    ro = np.empty(d)
    ro.flags.writeable = False
    cases = {
        "q": [
            np.full(2 * d, 0.3)[::2],
            np.full(d + 1, 0.3),
            np.full(d, 0.3, np.float32),
            np.full(d, 1),
            np.full(d, 0.3).astype(">f8"),
        ],
        "qd": [np.full(2 * d, 0.3)[::2], np.full(d - 1, 0.3)],
        "out": [np.empty(2 * d)[::2], np.empty(d + 1), np.empty(d, np.float32), ro, np.empty((1, d))],
    }
    for field, bad in cases.items():
        for a in bad:
            args = {"q": q, "qd": q, "qdd": q, "out": good, field: a}
            with pytest.raises(ValueError, match=f"field '{field}'"):
                model.inverse_dynamics(args["q"], args["qd"], args["qdd"], check=False, out=args["out"])
    with pytest.raises(ValueError, match="field 'qd'.*\\(q: \\(1, 15\\)\\)"):  # a batch of one against 1-D arrays
        model.inverse_dynamics(np.full((1, d), 0.3), q, q, check=False, out=good)
    assert np.isfinite(model.inverse_dynamics(q, q, q, check=False, out=good)).all()


def test_the_lean_kernel_holds_the_compiled_entry_and_every_form_of_the_call_agrees():
    """The lean kernel object holds the compiled validate-and-compute entry of one sample
    (model.inverse_dynamics stays the class's method: nothing is rebound, issue 35); each form of the call
    gives the same forces (the one-sample entry's or the checked path's), and misuse the same errors."""
    mech = exo5(3)
    model = prepare(mech, "matrix-factored")
    q, qd, qdd = (x[0].copy() for x in uniform_states(mech, 1, seed=11))
    want = model.inverse_dynamics(q, qd, qdd)
    out = np.empty(mech.dof)
    model.inverse_dynamics(q, qd, qdd, check=False, out=out)
    assert model._entries.inverse_fast is not None
    assert "inverse_dynamics" not in vars(model)
    forms = [
        ((q, qd, qdd), {"check": False, "out": out}),
        ((q, qd, qdd, False, out), {}),
        ((q, qd, qdd, False), {"out": out}),
        ((q, qd, qdd), {"out": out, "check": False}),
        ((q, qd, qdd), {}),
        ((q, qd, qdd), {"check": False}),
        ((q, qd, qdd), {"out": out}),
        ((q, qd, qdd), {"check": 0, "out": out}),
    ]
    for args, kw in forms:
        out[:] = np.nan
        got = model.inverse_dynamics(*args, **kw)
        assert np.abs(got - want).max() <= TOL * np.abs(want).max(), (len(args), kw)
    Q = np.stack([q, q])
    assert model.inverse_dynamics(Q, Q, Q, check=False).shape == (2, mech.dof)  # a batch: the method
    with pytest.raises(TypeError):
        model.inverse_dynamics(q, qd, qdd, check=False, out=out, extra=1)
    with pytest.raises(TypeError):
        model.inverse_dynamics(q, qd, qdd, False, out, check=False)
    with pytest.raises(ValueError, match="field 'out'"):
        model.inverse_dynamics(q, qd, qdd, check=False, out=np.empty(mech.dof + 1))
    twin = __import__("pickle").loads(__import__("pickle").dumps(model))  # pickles by reconstruction
    assert np.array_equal(twin.inverse_dynamics(q, qd, qdd), want)
    serial = np.empty(mech.dof)
    model.serial_kernel(model.kernel_args[0], q, qd, qdd, serial)
    assert np.array_equal(model.inverse_dynamics(q, qd, qdd, check=False, out=out), serial)


@pytest.mark.parametrize("dof", [2, 15, 3000])
def test_run_splits_a_batch_from_the_element_threshold_on(dof):
    """simd_blocks.run splits from PARALLEL_MIN_ELEMENTS state elements on (a 3D chain of 1000 from
    44 samples, exo5-3d from 8739), into shares of whole blocks that cover the batch once."""
    calls = []

    def spy(params, q, qd, qdd, o, start, stop):
        calls.append((start, stop))

    P = parallel_min_samples(dof)
    assert (P - 1) * dof < simd_blocks.PARALLEL_MIN_ELEMENTS <= P * dof
    for S, split in ((P - 1, False), (P, True), (P + 3 * L + 1, True)):
        calls.clear()
        x = np.zeros(S * dof)
        simd_blocks.run(spy, None, x, x, x, x, S, threads=2)
        assert (len(calls) > 1) == split, (S, calls)
        shares = sorted(calls)
        assert shares[0][0] == 0 and shares[-1][1] == S
        assert all(a[1] == b[0] for a, b in zip(shares, shares[1:]))
        assert all(start % L == 0 for start, _ in shares)
