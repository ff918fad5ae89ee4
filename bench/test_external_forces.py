"""Issue 37's f_ext speed as benchmark rows: one-sample inverse dynamics with and without ``f_ext``.

Users put ``f_ext`` in controllers and ODE right-hand sides, so a one-sample call with it should cost the
call without it plus the generalised forces ``Q(q, f_ext)`` (an O(n) pass, compiled:
models/runtime/external_forces.py). Each row times one public call (``model.inverse_dynamics(q, qd, qdd,
check=..., f_ext=...)``) on exo5-3d and on the 10-link human (``human-2d``), matrix-factored and
newton-euler, ``check`` True and False, without and with ``f_ext``: the rows of one mechanism are one
group (``f_ext-<mechanism>``), timed in one process, so ``py.test-benchmark compare`` reads the cost of
``f_ext`` as the ratio of a row with it to the same row without. Each row asserts its result (the call
without ``f_ext`` minus the numpy ``Q``, to the last bit); speed is reported, never asserted.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.runtime import external_forces as xf
from exo_bench.models.mechanism.presets import exo5, human, human_standing

MECHANISMS = {"exo5-3d": lambda: exo5(3), "human-2d": lambda: human(2)}
METHODS = ("matrix-factored", "newton-euler")


@pytest.fixture(scope="module")
def cases():
    """``{(mechanism, method): (model, q, qd, qdd, f)}``: one seeded state per mechanism (the human near
    standing, exo5 at moderate angles and lengths), forces of tens of newtons at every point."""
    out = {}
    for name, make in MECHANISMS.items():
        mech = make()
        rng = np.random.default_rng(37)
        if name.startswith("human"):
            q = human_standing(mech)[0] + 0.05 * rng.normal(size=mech.dof)
        else:
            q = np.r_[rng.uniform(-0.5, 0.5, 2 * mech.nlinks), rng.uniform(0.5, 1.0, mech.nlinks)]
        qd, qdd = rng.normal(size=(2, mech.dof))
        f = rng.normal(scale=40.0, size=(mech.nlinks, 3, mech.dim))
        for method in METHODS:
            out[(name, method)] = (prepare(mech, method), q, qd, qdd, f)
    return out


@pytest.mark.benchmark(max_time=0.25)
@pytest.mark.parametrize("with_f_ext", [False, True], ids=["plain", "f_ext"])
@pytest.mark.parametrize("check", [True, False], ids=["checked", "unchecked"])
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("mechanism", MECHANISMS)
def test_one_sample(benchmark, cases, mechanism, method, check, with_f_ext):
    model, q, qd, qdd, f = cases[(mechanism, method)]
    benchmark.group = f"f_ext-{mechanism}"
    benchmark.extra_info.update(
        method=method,
        mechanism=mechanism,
        samples=1,
        n=model.mechanism.nlinks,
        dim=model.mechanism.dim,
        check=check,
        f_ext=with_f_ext,
    )
    kw = {"f_ext": f} if with_f_ext else {}
    got = benchmark(model.inverse_dynamics, q, qd, qdd, check=check, **kw)
    want = model.inverse_dynamics(q, qd, qdd, check=check)
    if with_f_ext:
        want = want - xf.generalized_forces(model.mechanism, q[None], f[None])[0]
    assert np.array_equal(got, want)
