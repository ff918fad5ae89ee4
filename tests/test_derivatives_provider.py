"""``model.derivatives`` (issue 36): one analytic provider for every method (models/derivatives.py), no CasADi.

* Every installed method's ``prepare(mech, method).derivatives`` gives the same numbers (bit for bit: one
  provider, the mechanism's own equations of motion) and says its source.
* The provider's inverse-dynamics derivatives are the analytic kernels' (models/newton_euler/derivatives.py),
  bit for bit; CasADi's path (matrix_method/derivatives.py) stays reachable and agrees to the issue's 1e-13.
* No CasADi needed: with ``import casadi`` failing, the derivatives still answer and CasADi's path names its extra.
* Memory is estimated before the work: the estimate is the output (``3 S dof^2`` float64) plus O(n) per
  sample, and a call over the limit is refused before any kernel runs (counted, not allocated), at n = 300.
"""

from __future__ import annotations

import sys

import numpy as np
import pytest
from test_derivatives_analytic import states

from conftest import installed_methods
from exo_bench import prepare, presets
from exo_bench.models import derivatives as provider
from exo_bench.models.newton_euler.derivatives import prepare_inverse_derivatives
from exo_bench.models.mechanism.presets import random_tree

MECH = random_tree(5, 3, 17)


def test_every_method_gives_the_same_derivatives_and_says_its_source():
    """One provider: every installed method's derivatives equal newton-euler's bit for bit (inverse and
    forward), and each ``source`` names the analytic kernels and which equations they are for that method."""
    q, qd, qdd = states(MECH, 3, 1)
    ref_model = prepare(MECH, "newton-euler")
    tau = ref_model.inverse_dynamics(q, qd, qdd)
    ref = ref_model.derivatives.inverse_dynamics(q, qd, qdd) + ref_model.derivatives.forward_dynamics(q, qd, tau)
    assert "same equations that newton-euler evaluates" in ref_model.derivatives.source
    methods = [m for m in installed_methods() if m != "matrix-paper"]  # its misprinted 3D: below in 2D
    assert len(methods) >= 6, methods
    for method in methods:
        D = prepare(MECH, method).derivatives
        got = D.inverse_dynamics(q, qd, qdd) + D.forward_dynamics(q, qd, tau)
        for a, b in zip(got, ref):
            np.testing.assert_array_equal(a, b, err_msg=method)
        assert D.source.startswith("analytic O(n) derivatives of the Newton-Euler passes"), D.source
        assert "CasADi" not in D.source and (method in D.source or "unique" in D.source), D.source
    paper = prepare(presets.exo5(dim=2), "matrix-paper").derivatives.source
    assert "CORRECT equations" in paper


def test_the_provider_runs_the_analytic_kernels():
    """``model.derivatives.inverse_dynamics`` is the analytic kernels' call, bit for bit, batch and one
    sample; its forward ``qdd`` is newton-euler's forward dynamics."""
    q, qd, qdd = states(MECH, 4, 2)
    D = prepare(MECH, "matrix-factored").derivatives
    want = prepare_inverse_derivatives(MECH)(q, qd, qdd)
    for a, b in zip(D.inverse_dynamics(q, qd, qdd), want):
        np.testing.assert_array_equal(a, b)
    for a, b in zip(D.inverse_dynamics(q[1], qd[1], qdd[1]), want):
        np.testing.assert_array_equal(a, b[1])
    ne = prepare(MECH, "newton-euler")
    tau = ne.inverse_dynamics(q, qd, qdd)
    np.testing.assert_array_equal(D.forward_dynamics(q, qd, tau)[0], ne.forward_dynamics(q, qd, tau))


def test_casadis_path_stays_reachable_and_agrees():
    """``matrix_method.derivatives.derivatives_of`` is CasADi's AD behind the same calls (its source says
    so) and agrees with the analytic provider to 1e-13 relative to each sample's largest entry."""
    pytest.importorskip("casadi")
    from exo_bench.matrix_method.derivatives import derivatives_of

    q, qd, qdd = states(MECH, 3, 3)
    C = derivatives_of(MECH, "matrix-factored")
    assert C.source.startswith("CasADi algorithmic differentiation")
    D = prepare(MECH, "matrix-factored").derivatives
    for a, b in zip(D.inverse_dynamics(q, qd, qdd), C.inverse_dynamics(q, qd, qdd)):
        assert (np.abs(a - b).max(axis=(1, 2)) <= 1e-13 * np.abs(b).max(axis=(1, 2))).all()


def test_no_casadi_needed(monkeypatch):
    """With ``import casadi`` failing, ``model.derivatives`` answers (inverse, forward, products) and
    CasADi's path raises a ValueError naming the extra."""
    from exo_bench.matrix_method.export.casadi_functions import casadi_functions

    monkeypatch.setitem(sys.modules, "casadi", None)
    casadi_functions.cache_clear()
    try:
        mech = random_tree(3, 2, 99)
        q, qd, qdd = states(mech, 2, 4)
        D = prepare(mech, "matrix-factored").derivatives
        assert all(np.isfinite(x).all() for x in D.inverse_dynamics(q, qd, qdd))
        assert all(np.isfinite(x).all() for x in D.forward_dynamics(q, qd, qdd))
        assert np.isfinite(D.inverse_dynamics_jvp(q, qd, qdd, q, qd, qdd)).all()
        from exo_bench.matrix_method.derivatives import derivatives_of

        with pytest.raises(ValueError, match=r"extra 'casadi'"):
            derivatives_of(mech, "matrix-factored")
    finally:
        casadi_functions.cache_clear()


def test_the_memory_estimate_is_the_output_and_refuses_before_any_work(monkeypatch):
    """n = 300 in 3D (dof 900): the estimate of ``S`` samples is the three ``(S, dof, dof)`` float64
    Jacobians plus O(n) per sample (within 5% of the output alone for the compiled kernel), and a call
    over the limit raises :class:`DerivativesTooLarge` naming the estimate and the limit before any kernel
    is called (the kernels are counted, nothing that size is allocated)."""
    dof, S = 900, 200
    out = 3 * S * dof * dof * 8.0
    est = provider.derivative_bytes(dof, S)
    assert out <= est <= 1.05 * out  # O(n) per sample on top: 64 / (3 dof) = 2.4% here
    assert provider.derivative_bytes(dof, S, kernel="numpy") > est  # the numpy reference's columns as samples
    mech = presets.chain(300, dim=3, seed=1)
    assert mech.dof == dof
    D = provider.derivatives_of(mech, "newton-euler")
    calls = []
    for name in ("_inverse", "_accelerations", "_solve"):
        monkeypatch.setattr(D, name, lambda *a, _n=name, **k: calls.append(_n))
    monkeypatch.setattr(provider.memory, "usable_memory", lambda: int(est) - 1)
    q, qd, qdd = states(mech, S, 5)
    for call in (D.inverse_dynamics, D.forward_dynamics):
        with pytest.raises(
            provider.DerivativesTooLarge, match=rf"200 samples of 900 coordinates need about {est / 2**30:.2f} GiB"
        ):
            call(q, qd, qdd)
    assert calls == []
    assert isinstance(provider.DerivativesTooLarge("x"), MemoryError)
