"""Validation of states as one compiled pass (issue 35): models/states/validation_pass.py.

The compiled pass (``status`` for the verdict, ``locate`` for where the first problem is) is held to
the numpy reference of the same checks (``reference_status``, ``reference_locate``: the checks
``as_states`` made in numpy before) on seeded random states with NaN, inf, negative rod lengths,
``-0.0`` and values past the force bound injected at random positions; one sample and a batch agree;
and ``as_states`` names the array, the sample, the coordinate and the link the reference names."""

import functools
import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from exo_bench.models.states import validation_pass as vp
from exo_bench.models.states.states import as_states, coordinate_names
from exo_bench.models.mechanism.presets import exo5, random_tree
from exo_bench.models.states.states import checked_states, state_check
from exo_bench.models.states.validation import MAX_FORCE_SCALE, _where, force_scale_log10

LABELS = ("q", "qd", "qdd")


@functools.cache
def _mechanism(dim: int, nlinks: int, seed: int):
    return exo5(dim) if nlinks == 5 and seed == 0 else random_tree(nlinks, dim, seed)


def _run(kind: str, mech, arrays, reference: bool = False):
    """The verdict (``status``) or the first problem (``locate``) of the compiled pass, or of the
    numpy reference, for ``(q, qd, qdd)`` (None where missing)."""
    fn = vp.verdict if kind == "status" else vp.first_problem
    return fn(state_check(mech), arrays, reference=reference)


FAULTS = st.sampled_from(["nan", "inf", "-inf", "negative", "-0", "huge", "large"])


@st.composite
def cases(draw):
    dim = draw(st.sampled_from([2, 3]))
    nlinks = draw(st.sampled_from([1, 2, 5]))
    mech = _mechanism(dim, nlinks, draw(st.integers(0, 3)))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    samples = draw(st.integers(0, 40))
    count = draw(st.integers(1, 3))
    skip_qd = count == 3 and draw(st.booleans())  # as_states(mech, q, None, qdd) too
    arrays = [rng.normal(size=(samples, mech.dof)) for _ in range(count)]
    arrays[0][:, -nlinks:] = np.abs(arrays[0][:, -nlinks:])
    for _ in range(draw(st.integers(0, 3)) if samples else 0):
        k, s, c = draw(st.integers(0, count - 1)), draw(st.integers(0, samples - 1)), draw(st.integers(0, mech.dof - 1))
        fault = draw(FAULTS)
        if fault in ("negative", "-0"):
            k, c = 0, mech.dof - nlinks + c % nlinks
        value = {"nan": np.nan, "inf": np.inf, "-inf": -np.inf, "negative": -rng.uniform(1e-300, 2), "-0": -0.0}
        magnitude = 10.0 ** draw(st.sampled_from([150, 160, 300, 307])) if fault in ("huge", "large") else 0.0
        arrays[k][s, c] = value.get(fault, magnitude)
    if skip_qd:
        arrays[1] = None
    return mech, [*arrays, *[None] * (3 - count)]


@settings(max_examples=400, deadline=None)
@given(case=cases())
def test_compiled_pass_agrees_with_the_numpy_reference(case):
    """Verdict and position of the first problem: the compiled pass and the reference agree."""
    mech, arrays = case
    want = _run("status", mech, arrays, reference=True)
    assert _run("status", mech, arrays) == want
    where = _run("locate", mech, arrays)
    assert where == _run("locate", mech, arrays, reference=True)
    if want in (vp.NONFINITE, vp.NEGATIVE):
        assert where[0] == want


@settings(max_examples=200, deadline=None)
@given(case=cases())
def test_as_states_names_what_the_reference_finds(case):
    """``as_states`` accepts what the reference accepts (returning the arrays themselves, no copy) and
    otherwise names the array, the sample, the coordinate (and for a length the link) of the first
    problem the reference finds, or the force bound."""
    mech, arrays = case
    code = _run("status", mech, arrays, reference=True)
    if code == vp.OK:
        got = as_states(mech, *arrays)
        assert all(g is a for g, a in zip(got, arrays) if a is not None)
        return
    with pytest.raises(ValueError) as e:
        as_states(mech, *arrays)
    msg, names = str(e.value), coordinate_names(mech)
    if code == vp.BOUND:
        assert msg.startswith("states: the forces would overflow float64"), msg
        return
    _, k, s, c = _run("locate", mech, arrays, reference=True)
    value = arrays[k][s, c]
    if code == vp.NONFINITE:
        assert (
            msg
            == f"states: field '{LABELS[k]}' sample {s} coordinate {names[c]}: expected a finite number, got {value}"
        )
    else:
        i = c - (mech.dof - mech.nlinks)
        where = _where(i, mech.names[i])
        assert (
            msg
            == f"states: field 'q' sample {s} coordinate l{i + 1} ({where}): expected a rod length >= 0, got {value}"
        )


@settings(max_examples=200, deadline=None)
@given(case=cases())
def test_one_sample_and_batch_agree(case):
    """Each sample alone (1-D arrays) gets the verdict of the same sample as a batch of one; a batch
    passes only if every sample passes, and fails where its first failing sample fails (the force
    bound aside, which holds for the batch's largest values together)."""
    mech, arrays = case
    samples = arrays[0].shape[0]
    alone = []
    for s in range(samples):
        rows = [None if a is None else a[s] for a in arrays]
        one = _run("status", mech, rows)
        assert one == _run("status", mech, [None if a is None else a[s : s + 1] for a in arrays])
        assert one == _run("status", mech, rows, reference=True)
        alone.append(one)
    batch = _run("status", mech, arrays)
    if batch == vp.OK:
        assert set(alone) <= {vp.OK}
    bad = [code for code in alone if code != vp.OK]
    if bad and vp.BOUND not in alone:
        assert batch != vp.OK


def _at_bound(mech, field: str, direction: int) -> float:
    """The value of ``field`` (length, rate or acceleration, the others at 0) nearest the force bound:
    the largest accepted (direction -1) or the smallest refused (+1), found by bisection on the
    reference bound (:func:`force_scale_log10`), then refined ulp by ulp."""

    def refused(x: float) -> bool:
        kw = {"length": 0.0, "rate": 0.0, "acceleration": 0.0, field: x}
        return not force_scale_log10(mech, **kw) < math.log10(MAX_FORCE_SCALE)

    lo, hi = 0.0, 1e308
    for _ in range(2000):
        mid = lo + (hi - lo) / 2
        if mid in (lo, hi):
            break
        lo, hi = (lo, mid) if refused(mid) else (mid, hi)
    return hi if direction > 0 else lo


@pytest.mark.parametrize("field", ["length", "rate", "acceleration"])
@pytest.mark.parametrize("dim", [2, 3])
def test_force_bound_decided_alike_at_the_last_ulp(field, dim):
    """At the force bound itself, the largest accepted value and the next float up: the compiled pass
    and the reference decide exactly as :func:`force_scale_log10` does (it computes the same
    logarithms in the same order)."""
    mech = exo5(dim)
    n = mech.nlinks
    for direction in (-1, 1):
        x = _at_bound(mech, field, direction)
        for value in (np.nextafter(x, -np.inf), x, np.nextafter(x, np.inf)):
            arrays = [np.zeros((3, mech.dof)) for _ in LABELS]
            k, cols = {"length": (0, slice(-n, None)), "rate": (1, 0), "acceleration": (2, 4)}[field]
            arrays[k][1, cols] = value
            kw = {"length": 0.0, "rate": 0.0, "acceleration": 0.0, field: float(value)}
            want = vp.BOUND if not force_scale_log10(mech, **kw) < math.log10(MAX_FORCE_SCALE) else vp.OK
            assert _run("status", mech, arrays, reference=True) == want
            assert _run("status", mech, arrays) == want, (field, value)
            assert _run("status", mech, [a[1] for a in arrays]) == want


def test_checked_states_returns_c_ordered_float64_arrays_as_given():
    """The fast path: C-ordered float64 arrays come back as they are (one sample stays 1-D in
    ``checked_states``, is a ``(1, dof)`` view in ``as_states``); any other layout or dtype is
    converted at the edge and then checked by the same pass."""
    mech = exo5(3)
    q = np.full(mech.dof, 0.5)
    assert all(a is q for a in checked_states(mech, q, q, q))
    got = as_states(mech, q, q, q)
    assert all(a.shape == (1, mech.dof) and np.shares_memory(a, q) for a in got)
    batch = np.full((4, mech.dof), 0.5)
    q_, qd_, qdd_ = as_states(mech, batch, batch)
    assert q_ is batch and qd_ is batch and qdd_ is None
    fortran = np.asfortranarray(batch)
    single = batch.astype(np.float32)
    for other in (fortran, single, batch.tolist()):
        got = as_states(mech, other, other, other)
        assert all(a.flags.c_contiguous and a.dtype == np.float64 and a.shape == batch.shape for a in got)
    bad = np.asfortranarray(batch.copy())
    bad[2, 3] = np.nan
    with pytest.raises(
        ValueError, match=f"field 'qd' sample 2 coordinate {coordinate_names(mech)[3]}: expected a finite"
    ):
        as_states(mech, batch, bad)


def test_an_accepted_call_makes_no_numpy_reductions_and_no_names(monkeypatch):
    """Per call, the fast path builds no coordinate names and runs no numpy reduction (the compiled
    pass does the work); they are built only to name a problem."""
    from exo_bench.models.states import states

    mech = exo5(3)
    q = np.full(mech.dof, 0.5)
    as_states(mech, q, q, q)  # first call: the pass is loaded and the mechanism's constants are computed

    def refuse(*a, **k):
        raise AssertionError("called on the fast path")

    for name in ("isfinite", "argwhere", "abs", "any", "max"):
        monkeypatch.setattr(np, name, refuse)
    monkeypatch.setattr(states, "coordinate_names", refuse)
    as_states(mech, q, q, q)
    as_states(mech, np.full((3, mech.dof), 0.5), np.zeros((3, mech.dof)))


def test_the_pass_is_compiled_once():
    """One and the same compiled entry serves every mechanism and every batch size: calls do not add
    specialisations (compiling is seconds; a new signature per shape or mechanism would recompile)."""
    entries = vp.entries()
    before = [len(f.signatures) for f in (vp.status, vp.locate)]
    for dim, nlinks, seed in ((2, 1, 1), (3, 5, 0), (3, 2, 2)):
        mech = _mechanism(dim, nlinks, seed)
        for shape in ((mech.dof,), (1, mech.dof), (7, mech.dof), (0, mech.dof)):
            q = np.ones(shape)
            as_states(mech, q, q, q)
            q2 = q.copy()
            if q2.size:
                q2.flat[-1] = -1.0
                with pytest.raises(ValueError, match="expected a rod length >= 0"):
                    as_states(mech, q2, q, q)
    assert [len(f.signatures) for f in (vp.status, vp.locate)] == before
    assert vp.entries() is entries


def test_importing_the_mechanism_does_not_import_numba():
    """numba is loaded by the first checked call, not by ``import exo_bench.models.mechanism.mechanism``."""
    code = "import sys, exo_bench.models.mechanism.mechanism as m; m.Mechanism; print('numba' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "False", r.stderr


def test_the_numpy_reference_runs_under_numba_disable_jit(tmp_path):
    """Under ``NUMBA_DISABLE_JIT`` (the numpy kernels still run) the checks are the numpy reference,
    with the same messages. With an empty numba cache: a cached cfunc elsewhere hid a compile at import
    that fails under ``NUMBA_DISABLE_JIT`` (it failed on a fresh clone whose cache was in the workers'
    shared folder)."""
    code = (
        "import numpy as np\n"
        "from exo_bench.models.mechanism.presets import exo5\n"
        "from exo_bench.models.states.states import as_states\n"
        "m = exo5(3); q = np.full((50, m.dof), 0.3); as_states(m, q, q, q)\n"
        "q[7, 13] = -2.0\n"
        "try:\n    as_states(m, q, q, q)\nexcept ValueError as e:\n    print(e)\n"
    )
    env = {"NUMBA_DISABLE_JIT": "1", "PATH": "/usr/bin:/bin", "NUMBA_CACHE_DIR": str(tmp_path)}
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    assert "field 'q' sample 7 coordinate l4" in r.stdout and "expected a rod length >= 0, got -2.0" in r.stdout, r


def test_a_mechanism_pickles_after_a_checked_call():
    """The check kept with a mechanism pickles as numbers: the copy checks alike, its compiled entries
    resolved again on its first call."""
    import pickle

    mech = exo5(2)
    q = np.full(mech.dof, 0.5)
    as_states(mech, q, q, q)
    copy = pickle.loads(pickle.dumps(mech))
    assert copy == mech and state_check(copy).by_ndim is None
    q[-1] = -1.0
    with pytest.raises(ValueError, match="coordinate l5 .*: expected a rod length >= 0, got -1.0"):
        as_states(copy, q, q, q)
