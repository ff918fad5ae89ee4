"""The compiled call of ``f_ext`` (issue 37: one sample with ``f_ext`` at about the cost of the call without
it, models/runtime/external_forces.py): the same numbers as the numpy ``Q`` to the last bit for one sample
and a batch, with and without ``check``, for inverse and forward dynamics; the mechanism's parameters bound
once per model (work counted, not timed: bench/test_external_forces.py times it); the kernel's own size
checks (memory safety whatever it is given); a force that is not finite named, with ``out`` untouched;
every layout of ``f_ext`` the call accepts giving the same numbers; an engine keeping its own ``Q``.

No tolerance: the compiled kernel does the numpy code's arithmetic in the same order (``dest = tau - Q``
and ``tau + Q`` are the same one rounding in both), so equality is exact."""

from __future__ import annotations

import numpy as np
import pytest
from test_external_forces import _case

from exo_bench import prepare
from exo_bench.models.runtime import external_forces as xf
from exo_bench.models.runtime import external_forces as xc
from exo_bench.models.mechanism.presets import exo5, human, human_standing, random_tree

MECHS = [exo5(3), human(2), random_tree(4, 3, 5)]
METHODS = ("matrix-factored", "newton-euler")


@pytest.fixture(scope="module")
def models():
    return {(m.name, name): prepare(m, name) for m in MECHS for name in METHODS}


def _states(mech, seed):
    q, qd, qdd, f = _case(mech, seed, 3)
    if mech.name.startswith("human"):
        q[:] = human_standing(mech)[0] + 0.05 * np.random.default_rng(seed).normal(size=mech.dof)
    return q, qd, qdd, f


@pytest.mark.parametrize("mech", MECHS, ids=lambda m: m.name)
@pytest.mark.parametrize("method", METHODS)
def test_one_sample_and_batch_are_the_numpy_q_to_the_last_bit(mech, method, models):
    model = models[(mech.name, method)]
    q, qd, qdd, f = _states(mech, 11)
    Q = xf.generalized_forces(mech, q, f)
    for check in (True, False):
        batch = model.inverse_dynamics(q, qd, qdd, check=check, f_ext=f)
        assert np.array_equal(batch, model.inverse_dynamics(q, qd, qdd, check=check) - Q), (method, check)
        for s in range(q.shape[0]):
            one = model.inverse_dynamics(q[s], qd[s], qdd[s], check=check, f_ext=f[s])
            assert one.shape == (mech.dof,)
            assert np.array_equal(one, model.inverse_dynamics(q[s], qd[s], qdd[s], check=check) - Q[s])
            tau = one
            got = model.forward_dynamics(q[s], qd[s], tau, check=check, f_ext=f[s])
            assert np.array_equal(got, model.forward_dynamics(q[s], qd[s], tau + Q[s], check=check))
        got = model.forward_dynamics(q, qd, batch, check=check, f_ext=f)
        assert np.array_equal(got, model.forward_dynamics(q, qd, batch + Q, check=check))


def test_the_parameters_are_bound_once_per_model(monkeypatch):
    """No per-call rebuild: 40 calls of each kind, and of ``Q`` alone (``simulate``'s right-hand side
    with ``f_ext``), build the kernel's parameters once, on the model's first call: they are state of
    the prepared model, not of a module cache keyed on the mechanism."""
    built = []
    real = xc.parameters
    monkeypatch.setattr(xc, "parameters", lambda mech: built.append(mech.name) or real(mech))
    mech = exo5(3)
    model = prepare(mech, "newton-euler")
    q, qd, qdd, f = _states(mech, 3)
    for _ in range(40):
        tau = model.inverse_dynamics(q[0], qd[0], qdd[0], f_ext=f[0])
        model.inverse_dynamics(q, qd, qdd, check=False, f_ext=f)
        model.forward_dynamics(q[0], qd[0], tau, f_ext=f[0])
    assert built == [mech.name]
    for _ in range(40):
        model._external_forces(q, f)
    assert built == [mech.name]


def test_the_kernel_checks_its_sizes_and_touches_nothing_when_they_disagree():
    mech = exo5(3)
    apply, p = xc.kernel(), xc.parameters(mech)
    q, _, _, f = _states(mech, 5)
    q, f, tau = q.reshape(-1), f.reshape(-1), np.ones(q.size)
    bad_parent = p.copy()
    bad_parent[3] = 7.0  # link 3's parent after it
    n = q.size
    cases = {  # (params, q, f, tau, dest size, mode)
        "forces of two samples for three": (p, q, f[: -f.size // 3], tau, n, xc.MINUS),
        "q not whole samples": (p, q[:-1], f, tau[:-1], n - 1, xc.MINUS),
        "tau shorter than q": (p, q, f, tau[:-1], n, xc.MINUS),
        "dest shorter than q": (p, q, f, tau, n - 1, xc.PLUS),
        "a parent after its child": (bad_parent, q, f, tau, n, xc.PLUS),
        "parameters of no mechanism": (p[:-1], q, f, tau, n, xc.ONLY),
    }
    for what, (params, qq, ff, tt, size, mode) in cases.items():
        dest = np.full(size, 7.0)
        assert apply(params, qq, ff, tt, dest, mode, True) == xc.BAD_SIZE, what
        assert (dest == 7.0).all(), what
    dest = np.empty(q.size)
    assert apply(p, q, f, tau, dest, xc.MINUS, True) == xc.DONE


@pytest.mark.parametrize("method", METHODS)
def test_a_force_that_is_not_finite_is_named_and_out_is_untouched(method, models):
    mech = MECHS[0]
    model = models[(mech.name, method)]
    q, qd, qdd, f = _states(mech, 7)
    f = f[0].copy()
    f[2, 2, 0] = np.inf
    out = np.full(mech.dof, 3.0)
    msg = rf"field 'f_ext': sample 0, link 3 \({mech.names[2]!r}\), point 'end', component x: expected a finite"
    with pytest.raises(ValueError, match=msg):
        model.inverse_dynamics(q[0], qd[0], qdd[0], f_ext=f, out=out)
    assert (out == 3.0).all()
    with pytest.raises(ValueError, match=msg):
        model.forward_dynamics(q[0], qd[0], qdd[0], f_ext=f, out=out)
    assert (out == 3.0).all()
    # check=False checks no value, and hides none: the infinite force shows in the result
    assert not np.isfinite(model.inverse_dynamics(q[0], qd[0], qdd[0], check=False, f_ext=f)).all()


def test_every_layout_of_f_ext_gives_the_same_numbers(models):
    mech = MECHS[1]
    model = models[(mech.name, "newton-euler")]
    q, qd, qdd, f = _states(mech, 9)
    f32 = f.astype(np.float32)
    want = model.inverse_dynamics(q, qd, qdd, f_ext=f32.astype(float))
    one = model.inverse_dynamics(q[1], qd[1], qdd[1], f_ext=f32[1].astype(float))
    wide = np.zeros((*f.shape[:-1], 2 * mech.dim), np.float32)
    wide[..., ::2] = f32
    for layout in (f32, f32.tolist(), np.asfortranarray(f32), wide[..., ::2]):
        assert np.array_equal(model.inverse_dynamics(q, qd, qdd, f_ext=layout), want)
        assert np.array_equal(model.inverse_dynamics(q[1], qd[1], qdd[1], f_ext=layout[1]), one)
    for layout in (np.asfortranarray(f32), wide[..., ::2]):  # arrays: converted, never read in place
        assert np.array_equal(model.inverse_dynamics(q, qd, qdd, check=False, f_ext=layout), want)


def test_an_engine_keeps_its_own_generalized_forces(models):
    pytest.importorskip("pinocchio")
    mech = MECHS[0]
    assert xc.bound(prepare(mech, "pinocchio")).apply is None
    assert xc.bound(models[(mech.name, "newton-euler")]).apply is not None
