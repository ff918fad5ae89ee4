"""The public calls and the directional derivatives predict their memory before the work (issue 34:
"Budgets and memory are predicted before the work"; "check=False skips validation of values, never of
memory safety").

A batch too large for the memory a run may use (:func:`exo_bench.models.machine.memory.usable_memory`, patched
here to 100 MiB) is refused by :class:`exo_bench.models.machine.memory.CallTooLarge` (a ``MemoryError``) naming
the call, the samples and the bytes, before the states are copied: the batches are read-only
``np.broadcast_to`` views (no real memory), and tracemalloc counts what the refusal allocated (no clock).
Before the estimate, the states were converted first (C-ordered copies, 16 MB each here, 80 GB each
at 10^9 samples of exo5-2d) and the call died in numpy's raw "Unable to allocate".
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.machine import memory
from exo_bench.models.mechanism.presets import exo5

MECH = exo5(2)
MODEL: dict = {}
SAMPLES = 10**6  # 80 MB per (samples, dof) copy at exo5-2d's 10 dof; over 100 MiB with the result


def _model():
    if not MODEL:
        MODEL["m"] = prepare(MECH, "newton-euler")
    return MODEL["m"]


def _calls():
    z = np.broadcast_to(np.zeros(MECH.dof), (SAMPLES, MECH.dof))
    f = np.broadcast_to(np.zeros((MECH.nlinks, 3, MECH.dim)), (SAMPLES, MECH.nlinks, 3, MECH.dim))
    return {
        "inverse_dynamics": lambda m, c: m.inverse_dynamics(z, z, z, check=c),
        "inverse_dynamics f_ext": lambda m, c: m.inverse_dynamics(z, z, z, check=c, f_ext=f),
        "forward_dynamics": lambda m, c: m.forward_dynamics(z, z, z, check=c),
        "forward_dynamics f_ext": lambda m, c: m.forward_dynamics(z, z, z, check=c, f_ext=f),
        "mass_matrix": lambda m, c: m.mass_matrix(z, check=c),
        "bias_forces": lambda m, c: m.bias_forces(z, z, check=c),
        "mass_matrix_and_bias": lambda m, c: m.mass_matrix_and_bias(z, z, check=c),
        "inverse_dynamics_jvp": lambda m, c: m.derivatives.inverse_dynamics_jvp(z, z, z, z, z, z, check=c),
        "inverse_dynamics_vjp": lambda m, c: m.derivatives.inverse_dynamics_vjp(z, z, z, z, check=c),
        "forward_dynamics_jvp": lambda m, c: m.derivatives.forward_dynamics_jvp(z, z, z, z, z, z, check=c),
        "forward_dynamics_vjp": lambda m, c: m.derivatives.forward_dynamics_vjp(z, z, z, z, check=c),
    }


@pytest.mark.parametrize("check", [True, False], ids=["check", "no-check"])
@pytest.mark.parametrize("call", list(_calls()))
def test_a_batch_too_large_is_refused_before_its_states_are_copied(monkeypatch, call, check):
    from exo_bench.models.machine.memory import CallTooLarge

    m = _model()
    m.derivatives  # built outside the count
    monkeypatch.setattr(memory, "usable_memory", lambda: 100 * 2**20)
    tracemalloc.start()
    try:
        with pytest.raises(CallTooLarge, match=f"{SAMPLES} samples of {MECH.dof} coordinates") as err:
            _calls()[call](m, check)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert isinstance(err.value, MemoryError)
    assert "GiB" in str(err.value) and "\n" not in str(err.value)
    assert peak < 2**20, f"{peak / 2**20:.1f} MiB allocated before the refusal"


def test_the_derivatives_refusal_is_the_same_mechanism():
    """One mechanism, one limit: the full Jacobians' refusal is a CallTooLarge too."""
    from exo_bench.models.derivatives import DerivativesTooLarge
    from exo_bench.models.machine.memory import CallTooLarge

    assert issubclass(DerivativesTooLarge, CallTooLarge)


def test_a_batch_that_fits_is_computed_as_before(monkeypatch):
    """The estimate refuses only what exceeds the limit: a batch under it gives the forces of one sample
    repeated (the broadcast states are one state)."""
    m = _model()
    q = np.linspace(0.1, 1.0, MECH.dof)
    one = m.inverse_dynamics(q, q, q)
    monkeypatch.setattr(memory, "usable_memory", lambda: 100 * 2**20)
    z = np.broadcast_to(q, (1000, MECH.dof))
    np.testing.assert_array_equal(m.inverse_dynamics(z, z, z), np.broadcast_to(one, (1000, MECH.dof)))
