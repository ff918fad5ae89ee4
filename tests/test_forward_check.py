"""Forward dynamics' compiled checks (models/forward_check.py) decide only the common case:
where they say a state is clear, the exact numpy checks (models/singularity.py,
models/conditioning.py) find nothing; near a bound the exact checks decide. Newton-euler's one
sample, checked, runs them and its forward passes in one compiled call (``tree-forward``) and refuses
what its batch refuses, with the same message; the other methods keep their own forward dynamics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from exo_bench import prepare
from exo_bench.models.conditioning import CONDITION_LIMIT, PIVOT_MIN, conditioning_reasons
from exo_bench.models.motion import random_states
from exo_bench.models.presets import exo5, random_tree
from exo_bench.models.singularity import SingularConfigurationError, singular_reasons


def _exact_refuses(model, q2) -> list[bool]:
    """Per sample of ``q2 (S, dof)``: the exact checks refuse it."""
    mech, c = model.mechanism, model.coupling_condition
    return [
        bool(singular_reasons(mech, q2[s : s + 1])[0] or conditioning_reasons(mech, q2[s : s + 1], c))
        for s in range(len(q2))
    ]


def _hard_states(mech, seed: int) -> np.ndarray:
    """Random states with rods tilted towards vertical, rods shortened towards ``PIVOT_MIN`` and angles
    grown, each spread over the bounds (clear, near, beyond)."""
    q, _, _ = random_states(mech, 64, seed)
    rng = np.random.default_rng(seed)
    n = mech.nlinks
    for s in range(len(q)):
        i, kind = int(rng.integers(n)), s % 4
        if kind == 1 and mech.dim == 3:
            q[s, n + i] = math.copysign(math.pi / 2 - 10.0 ** rng.uniform(-16, -3), q[s, n + i])
        elif kind == 2:
            q[s, -n + i] = PIVOT_MIN * 10.0 ** rng.uniform(-3, 3) * (0.0 if rng.random() < 0.1 else 1.0)
        elif kind == 3:
            q[s, i] = rng.choice([-1, 1]) * CONDITION_LIMIT / model_kappa(mech) * 10.0 ** rng.uniform(-1, 0.3)
    return q


def model_kappa(mech) -> float:
    return prepare(mech, "matrix-factored").coupling_condition.kappa


@settings(max_examples=12, deadline=None, derandomize=True, database=None)
@given(dim=st.sampled_from([2, 3]), seed=st.integers(0, 2**16))
def test_where_the_compiled_check_says_clear_the_exact_checks_find_nothing(dim, seed):
    """Sample by sample, ``clear`` implies the exact checks pass, and every sample the exact checks
    refuse is not clear (hypothesis, states spread over the bounds); both verdicts occur."""
    mech = [exo5(dim), random_tree(6, dim, seed)][seed % 2]
    model = prepare(mech, "matrix-factored")
    clear, _ = model._resolve_forward_checks()
    q = _hard_states(mech, seed)
    refused = _exact_refuses(model, q)
    verdicts = [clear(np.ascontiguousarray(q[s])) for s in range(len(q))]
    for s, (ok, no) in enumerate(zip(verdicts, refused)):
        assert not (ok and no), (s, q[s])
    assert any(verdicts) and any(refused)
    assert clear(q) == all(verdicts)


def test_finite_says_no_for_nan_and_inf_only():
    model = prepare(exo5(3), "matrix-factored")
    _, finite = model._resolve_forward_checks()
    a = np.linspace(-1.0, 1.0, 15) * 1.7e308  # x - x of the largest floats is 0; a sum would overflow
    assert np.isfinite(a).all()
    assert finite(a)
    for bad in (np.nan, np.inf, -np.inf):
        b = a.copy()
        b[7] = bad
        assert not finite(b)


@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
@pytest.mark.parametrize("dim", [2, 3])
def test_one_sample_checked_is_the_unchecked_answer_and_agrees_with_the_batch(dim, method):
    """A method's one sample, checked, returns the unchecked one sample's answer bit for bit, and
    agrees with its batch (matrix-factored's: a Cholesky solve of its own M and h) to the error model's
    K eps kappa."""
    from conftest import EPS, K

    mech = exo5(dim)
    model = prepare(mech, method)
    q, qd, _ = random_states(mech, 8, 3)
    tau = np.random.default_rng(3).uniform(-20, 20, q.shape)
    batch = model.forward_dynamics(q, qd, tau)
    kappa = (
        model.coupling_condition.kappa
        * max(1.0, np.abs(q[:, : -mech.nlinks]).max())
        / (np.abs(np.cos(q[:, mech.nlinks : 2 * mech.nlinks])).min() ** 2 if dim == 3 else 1.0)
    )
    for s in range(len(q)):
        one = model.forward_dynamics(q[s], qd[s], tau[s])
        assert np.array_equal(one, model.forward_dynamics(q[s], qd[s], tau[s], check=False))
        w = np.sqrt(np.diagonal(model.mass_matrix(q[s])))
        err = np.linalg.norm(w * (one - batch[s])) / np.linalg.norm(w * batch[s])
        assert err <= 2 * K * EPS * kappa, (s, err)


@pytest.mark.parametrize(
    "what", ["l5=1e-300", "l2=0", "psi3=pi/2-1e-8", "psi3=pi/2", "phi1=1e12", "massless", "overflow"]
)
@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
def test_one_sample_refuses_what_its_batch_refuses_with_the_same_message(what, method):
    """A refused state refuses as one sample (the compiled path, then the exact checks) with the message of
    the batch of that one sample, and leaves ``out`` untouched."""
    mech = exo5(3)
    n = mech.nlinks
    if what == "massless":
        mech = mech.replace(masses=(*mech.masses[:4], (0.0, 0.0, 0.0)))
    if what == "overflow":
        mech = mech.replace(masses=tuple(tuple(m * 1e-12 for m in ms) for ms in mech.masses))
    q, qd, _ = random_states(mech, 1, 5)
    tau = np.zeros_like(q)
    key, _, value = what.partition("=")
    if key == "overflow":
        tau[0, 4] = 1e299
    elif key.startswith("l"):
        q[0, 2 * n + int(key[1]) - 1] = float(value)
    elif key.startswith("psi"):
        q[0, n + 2] = math.pi / 2 - (float(value.split("-", 1)[1]) if "-" in value else 0.0)
    elif key.startswith("phi"):
        q[0, 0] = float(value)
    model = prepare(mech, method)
    with pytest.raises(SingularConfigurationError) as whole, np.errstate(all="ignore"):
        model.forward_dynamics(q, qd, tau)
    out = np.full(mech.dof, 7.0)
    with pytest.raises(SingularConfigurationError) as one, np.errstate(all="ignore"):
        model.forward_dynamics(q[0], qd[0], tau[0], out=out)
    if what == "overflow":  # each names the first coordinate its own answer overflows in (Cholesky, passes)
        assert str(one.value).split(" coordinate ")[0] == str(whole.value).split(" coordinate ")[0]
        assert "sample 0: field 'qdd' coordinate" in str(one.value) and "not finite" in str(one.value)
    else:
        assert str(one.value) == str(whole.value)
    assert (out == 7.0).all()


@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
def test_a_clear_one_sample_runs_no_exact_check(monkeypatch, method):
    """The common case costs one compiled call: the exact checks are not called (they would raise)."""
    from exo_bench.models import prepared

    mech = exo5(3)
    model = prepare(mech, method)
    q, qd, qdd = random_states(mech, 1, 2)

    def refuse(*args, **kw):
        raise AssertionError("the exact check ran")

    monkeypatch.setattr(prepared, "singular_reasons", refuse)  # PreparedModel.check_regular's
    monkeypatch.setattr(prepared, "check_conditioning", refuse)
    monkeypatch.setattr(prepared, "check_finite", refuse)
    assert np.isfinite(model.forward_dynamics(q[0], qd[0], qdd[0])).all()
    assert np.isfinite(model.forward_dynamics(q, qd, qdd)).all()  # the batch's checks too


@pytest.mark.parametrize("where", [0, 5, 7, 12])
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_nan_or_inf_clears_nothing(where, bad):
    """``check_regular`` is public: a state with NaN or inf is never cleared by the compiled pass (the exact
    checks then refuse it by name)."""
    model = prepare(exo5(3), "matrix-factored")
    clear, _ = model._resolve_forward_checks()
    q, _, _ = random_states(model.mechanism, 2, 1)
    assert clear(q) and clear(np.ascontiguousarray(q[0]))
    q[1, where] = bad
    assert not clear(q) and not clear(np.ascontiguousarray(q[1]))
    with pytest.raises(ValueError):
        model.check_regular(q)


@pytest.mark.parametrize("method", ["newton-euler", "matrix-factored"])
def test_one_sample_unchecked_at_a_singular_state_is_named_not_a_bare_zero_division(method):
    """``check=False`` checks no value, but a division by zero in the passes (a rod of length zero) is not
    let out as a bare ZeroDivisionError: the default method's one sample names the link (its batch's
    Cholesky solve names the zero pivot: a SingularConfigurationError too)."""
    mech = exo5(3)
    model = prepare(mech, method)
    q, qd, _ = random_states(mech, 1, 1)
    q[0, 2 * mech.nlinks + 2] = 0.0
    tau = np.zeros_like(q)
    with pytest.raises(SingularConfigurationError, match="link 3"):
        model.forward_dynamics(q[0], qd[0], tau[0], check=False)
