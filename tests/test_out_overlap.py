"""``check=False`` skips values, never memory safety: an ``out`` that shares memory with an input is
refused (issue 34, W5).

The kernels write ``out`` while they read ``q``, ``qd`` and ``qdd`` (or ``tau``): an ``out`` that
overlapped an input by even one element gave errors of 1e7 to 1e277 and NaN, with no word; only an
exact alias was caught. The test is numpy's bounds test (O(1)), in Python (models/array_gate.py), and a
comparison of the data pointers in the kernels' compiled one-sample entries (models/validation_pass.py)."""

import numpy as np
import pytest
from conftest import assert_forces_agree, installed_methods
from hypothesis import given, settings
from hypothesis import strategies as st

from exo_bench import prepare
from exo_bench.models.motion import random_states
from exo_bench.models.presets import exo5

MECH = exo5(3)
DOF = MECH.dof
FAST = [m for m in ("matrix-factored", "newton-euler", "matrix", "recurrence", "pinocchio")]


def _models():
    return {m: prepare(MECH, m) for m in FAST if m in installed_methods()}


MODELS: dict = {}


def _model(method):
    if not MODELS:
        MODELS.update(_models())
    model = MODELS[method]
    for _ in range(3):  # past the first calls: the compiled wrapper replaces the method after one lean call
        model.inverse_dynamics(*(np.zeros(DOF) + 0.3 for _ in range(3)), check=False, out=np.empty(DOF))
    return model


@pytest.mark.case("W5")
@settings(max_examples=40, deadline=None)
@given(
    method=st.sampled_from(FAST),
    which=st.sampled_from(["q", "qd", "qdd"]),
    shift=st.integers(-(DOF - 1), DOF - 1),
    samples=st.sampled_from([None, 1, 3]),
)
def test_an_out_that_overlaps_an_input_is_refused_with_check_false(method, which, shift, samples):
    """An ``out`` overlapping q, qd or qdd by any number of elements, one sample or a batch, is refused with
    check=False too, naming the field it overlaps; the inputs are left as they were."""
    q, qd, qdd = random_states(MECH, samples or 1, 5)
    rows = samples or 1
    size = rows * DOF
    buf = np.zeros(3 * size + 2 * DOF)
    start = DOF
    states = {"q": q, "qd": qd, "qdd": qdd}
    view = buf[start : start + size]
    view[:] = states[which].reshape(-1)
    states[which] = view.reshape(q.shape) if samples else view
    out = buf[start + shift : start + shift + size]
    out = out.reshape(q.shape) if samples else out
    args = [states[k] if samples or k == which else states[k][0] for k in ("q", "qd", "qdd")]
    before = [a.copy() for a in args]
    with pytest.raises(ValueError, match=f"field 'out': .*overlaps '{which}'"):
        _model(method).inverse_dynamics(*args, check=False, out=out)
    assert all(np.array_equal(a, b) for a, b in zip(args, before))


@pytest.mark.case("W5")
@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
def test_forward_dynamics_refuses_an_out_that_overlaps_tau(method):
    """Forward dynamics with check=False refuses an ``out`` that overlaps ``tau``, naming it."""
    if method not in installed_methods():
        pytest.skip(f"{method} not installed")
    model = prepare(MECH, method)
    q, qd, qdd = random_states(MECH, 2, 1)
    tau = model.inverse_dynamics(q, qd, qdd)
    buf = np.concatenate([tau.reshape(-1), np.zeros(DOF)])
    with pytest.raises(ValueError, match="field 'out': .*overlaps 'tau'"):
        model.forward_dynamics(q, qd, buf[: 2 * DOF].reshape(2, DOF), check=False, out=buf[DOF:].reshape(2, DOF))


@pytest.mark.parametrize("method", FAST)
def test_an_out_beside_the_inputs_in_one_buffer_is_used(method):
    """Not a refusal by accident: inputs and ``out`` side by side in one buffer, touching but apart, give the
    forces of separate arrays."""
    if method not in installed_methods():
        pytest.skip(f"{method} not installed")
    q, qd, qdd = random_states(MECH, 1, 2)
    buf = np.concatenate([q[0], qd[0], qdd[0], np.zeros(DOF)])
    views = [buf[i * DOF : (i + 1) * DOF] for i in range(4)]
    model = _model(method)
    got = model.inverse_dynamics(*views[:3], check=False, out=views[3])
    assert got is views[3]
    ref = prepare(MECH, "pinocchio").inverse_dynamics(q, qd, qdd)
    assert_forces_agree(got[None], ref, MECH, q, qd, qdd)
