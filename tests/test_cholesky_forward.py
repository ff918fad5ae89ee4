"""matrix-factored's forward dynamics of one sample (kernel ``cholesky-forward``,
matrix_method/numba_kernels/cholesky_forward.py): ``h`` by the factored kernel and ``M = R^T (C x I) R``
solved through the Cholesky factor of the coupling, in one compiled call, never forming ``M``.

Error model (backward error, as bench/test_forward_dynamics.py): the answer ``qdd`` of a solver that is
backward stable in the factored form satisfies ``M qdd + h = tau`` up to a residual of ``k eps dof``
times the scale ``|tau| + |M qdd| + |h|`` (k = 16: the product ``R^T C^-1 R`` has three factors of at
most ~4 roundings each, two triangular solves of ``n`` terms summed at ``eps`` per level). The residual
is computed by another method's inverse dynamics (newton-euler's passes), so the oracle shares no code
with the kernel.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, random_tree

K_BACKWARD = 16


def _backward_error(ne, q, qd, tau, qdd) -> tuple[float, float]:
    """``(|ID(q, qd, qdd) - tau|, k eps dof scale)`` by newton-euler's inverse dynamics."""
    eps, zero = float(np.finfo(float).eps), np.zeros_like(qdd)
    h = ne.inverse_dynamics(q, qd, zero, check=False)
    mq = ne.inverse_dynamics(q, zero, qdd, check=False) - ne.inverse_dynamics(q, zero, zero, check=False)
    scale = np.abs(tau).max() + np.abs(mq).max() + np.abs(h).max()
    residual = ne.inverse_dynamics(q, qd, qdd, check=False) - tau
    return float(np.abs(residual).max()), K_BACKWARD * eps * q.shape[-1] * float(scale)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_sample_solves_the_equations_on_random_trees(dim, seed):
    """Checked and unchecked one-sample answers are the same bits, and solve ``M qdd + h = tau`` within the
    backward error bound (module docstring) on seeded random trees."""
    mech = random_tree(6, dim, seed)
    mf, ne = prepare(mech, "matrix-factored"), prepare(mech, "newton-euler")
    q, qd, _ = random_states(mech, 4, seed)
    tau = np.random.default_rng(seed).uniform(-30, 30, q.shape)
    for s in range(len(q)):
        one = mf.forward_dynamics(q[s], qd[s], tau[s])
        assert np.array_equal(one, mf.forward_dynamics(q[s], qd[s], tau[s], check=False))
        err, bound = _backward_error(ne, q[s], qd[s], tau[s], one)
        assert err <= bound, (s, err, bound)


def test_one_sample_forms_no_mass_matrix(monkeypatch):
    """One sample, checked or not, runs the compiled kernel: neither ``mass_matrix_and_bias`` nor the numpy
    Cholesky solve is called (seen failing before the kernel: the generic route called both)."""
    mech = exo5(3)
    mf = prepare(mech, "matrix-factored")
    q, qd, qdd = random_states(mech, 1, 4)

    def refuse(*args, **kw):
        raise AssertionError("the numpy route ran")

    monkeypatch.setattr(type(mf), "mass_matrix_and_bias", refuse)
    out = np.empty(mech.dof)
    assert mf.forward_dynamics(q[0], qd[0], qdd[0], check=False, out=out) is out
    assert np.array_equal(mf.forward_dynamics(q[0], qd[0], qdd[0]), out)
    assert np.isfinite(out).all()


def test_kernel_declines_a_singular_state_and_writes_nothing():
    """The compiled call answers False and leaves ``o`` untouched where ``M`` is singular: a rod of length
    zero (``cos psi`` of a float is never exactly zero: a vertical rod is the checks' to refuse), a length
    that is not finite."""
    from exo_bench.matrix_method.numba_kernels.cholesky_forward import entries

    mech = exo5(3)
    mf = prepare(mech, "matrix-factored")
    n, e = mech.nlinks, entries()
    lc = np.ascontiguousarray(np.linalg.cholesky(mf.coupling))
    q, qd, qdd = random_states(mech, 1, 6)
    for index, value in ((2 * n + 1, 0.0), (2 * n + 2, -0.0), (2 * n, np.inf), (2 * n + 4, np.nan)):
        x = q[0].copy()
        x[index] = value
        o = np.full(mech.dof, 7.0)
        assert not e.forward_sample(mf.kernel_args[0], lc, x, qd[0], qdd[0], o), (index, value)
        assert (o == 7.0).all()
    o = np.empty(mech.dof)
    assert e.forward_sample(mf.kernel_args[0], lc, np.ascontiguousarray(q[0]), qd[0], qdd[0], o)
