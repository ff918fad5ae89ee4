"""Every method's inverse and forward dynamics with ``f_ext`` (issue 37) on seeded random trees in 2D and
3D, against newton-euler's numpy passes minus the numpy ``Q``; and ``f_ext`` checked at the edge (shape
always, values with ``check``) and built by name. Error model: tests/test_external_forces.py (inverse
dynamics); forward dynamics amplifies the rounding of ``tau + Q`` by at most ``cond(M)``, as in
tests/test_forward_dynamics.py (``10 eps cond(M)`` relative), with ``|tau| + |Q|`` in place of ``|tau|``."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, K, assert_close, installed_methods, term_scale
from test_external_forces import _case, external_force_scale

from exo_bench import prepare
from exo_bench.models.runtime import external_forces as xf
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.mechanism.presets import exo5, random_tree

SMALL = [random_tree(3, 2, 4), random_tree(3, 3, 7)]  # lagrange derives each (2-6 s)
#: Their own Q: tests/test_external_forces_engines.py; matrix-paper is eq. (18) as printed, wrong in 3D by
#: design (it warns), and takes f_ext by the same one call.
ENGINES = {"mujoco", "drake", "matrix-paper"}


@pytest.fixture(scope="module")
def models():
    return {(m.name, name): prepare(m, name) for m in SMALL for name in installed_methods() if name not in ENGINES}


@pytest.mark.parametrize("mech", SMALL, ids=lambda m: m.name)
def test_every_method_inverse_and_forward_with_f_ext(mech, models):
    q, qd, qdd, f = _case(mech, 31, 3)
    ref = prepare(mech, "newton-euler", kernel="numpy")
    want = ref.inverse_dynamics(q, qd, qdd) - xf.generalized_forces(mech, q, f)
    scale = term_scale(mech, q, qd, qdd) + external_force_scale(mech, q, f)
    cond = fd.condition_numbers(ref.mass_matrix(q))[0].max()
    Q = np.abs(xf.generalized_forces(mech, q, f)).max()
    for (name, method), model in models.items():
        if name != mech.name:
            continue
        tau = model.inverse_dynamics(q, qd, qdd, f_ext=f)
        assert_close(tau, want, scale, K, f"{method}: inverse dynamics with f_ext")
        one = model.inverse_dynamics(q[0], qd[0], qdd[0], f_ext=f[0])  # one sample: (links, 3, dim)
        assert_close(one, want[0], scale[0], K, f"{method}: one sample")
        got = model.forward_dynamics(q, qd, want, f_ext=f)
        growth = (np.abs(want).max() + Q) / np.abs(want).max()
        err = np.abs(got - qdd).max() / np.abs(qdd).max()
        assert err < 10 * EPS * cond * growth, (method, err / (EPS * cond * growth))
        fast = model.forward_dynamics(q, qd, want, check=False, f_ext=f)
        assert np.array_equal(fast, got), method  # check never changes the numbers


def test_out_and_check_false_give_the_same_numbers():
    mech = SMALL[1]
    model = prepare(mech, "newton-euler")
    q, qd, qdd, f = _case(mech, 2, 4)
    a = model.inverse_dynamics(q, qd, qdd, f_ext=f)
    out = np.empty_like(q)
    assert model.inverse_dynamics(q, qd, qdd, f_ext=f, out=out) is out
    assert np.array_equal(out, a)
    assert np.array_equal(model.inverse_dynamics(q, qd, qdd, check=False, f_ext=f), a)
    assert np.array_equal(
        model.inverse_dynamics(q, qd, qdd, f_ext=np.zeros_like(f)), model.inverse_dynamics(q, qd, qdd)
    )


@pytest.mark.parametrize("check", [True, False])
def test_a_wrong_shape_is_refused_with_or_without_check(check):
    mech = SMALL[1]
    model = prepare(mech, "newton-euler")
    q, qd, qdd, f = _case(mech, 2, 2)
    for bad in (f[:, :2], f[0], f[..., :2], np.zeros((2, 3, 3 * 3))):
        with pytest.raises(ValueError, match=r"field 'f_ext': expected forces of shape \(2, 3, 3, 3\).* got \("):
            model.inverse_dynamics(q, qd, qdd, check=check, f_ext=bad)
        with pytest.raises(ValueError, match="field 'f_ext'"):
            model.forward_dynamics(q, qd, qdd, check=check, f_ext=bad)


def test_a_nan_is_named_by_sample_link_and_point():
    mech = exo5(3)
    model = prepare(mech, "newton-euler")
    q = np.tile(np.r_[np.zeros(2 * mech.nlinks), np.ones(mech.nlinks)], (2, 1))
    f = np.zeros((2, mech.nlinks, 3, 3))
    f[1, 2, 1, 2] = np.nan
    msg = rf"field 'f_ext': sample 1, link 3 \({mech.names[2]!r}\), point 'middle', component z: expected a finite"
    with pytest.raises(ValueError, match=msg):
        model.inverse_dynamics(q, q * 0, q * 0, f_ext=f)
    with pytest.raises(ValueError, match=msg):
        model.forward_dynamics(q, q * 0, q * 0, f_ext=f)
    with pytest.raises(ValueError, match="field 'tau': expected an array of the shape of q"):
        model.forward_dynamics(q, q * 0, q[0] * 0, f_ext=f * 0)


def test_forces_by_name():
    mech = exo5(2)
    a, b = mech.names[0], mech.names[3]
    f = xf.forces_at(mech, {(a, "end"): [1.0, 2.0], (b, "start"): [0.0, -9.0]})
    want = np.zeros((mech.nlinks, 3, 2))
    want[0, 2], want[3, 0] = [1.0, 2.0], [0.0, -9.0]
    assert np.array_equal(f, want)
    batch = xf.forces_at(mech, {(a, "middle"): np.ones((4, 2))}, samples=4)
    assert batch.shape == (4, mech.nlinks, 3, 2) and batch[:, 0, 1].sum() == 8
    with pytest.raises(ValueError, match=rf"link 'heel': expected one of {mech.names[0]!r}"):
        xf.forces_at(mech, {("heel", "end"): [0.0, 1.0]})
    with pytest.raises(ValueError, match="point 'toe': expected one of start, middle, end"):
        xf.forces_at(mech, {(a, "toe"): [0.0, 1.0]})
    with pytest.raises(ValueError, match=r"expected a force of shape \(2,\), got \(3,\)"):
        xf.forces_at(mech, {(a, "end"): [0.0, 1.0, 2.0]})
