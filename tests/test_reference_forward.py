"""The analytic forward-dynamics derivatives (``model.derivatives.forward_dynamics``: ``M^-1`` by columns of
the O(n) forward dynamics, no dense LU) against the 50-digit reference on seeded random trees with branch
signs, 2D and 3D: issue 36's done-when asks the analytic derivatives to agree with it up to n = 100.

**The reference** (:func:`exo_bench.lagrange.derivative_reference.forward_derivatives`): ``qdd`` and ``M^-1``
by a 50-digit Gauss-Jordan solve, then ``-M^-1 dID/dq`` and ``-M^-1 dID/dqd`` as 50-digit products. Its cost
grows as ``dof^3`` (one sample, CPU seconds, gmpy2, measured at load 8-9): 3D n = 10 (30 dof) 0.11 s, n = 20
0.62 s, n = 30 2.4 s, n = 40 5.5 s; the two n = 100 trees took 65 s (2D, 200 dof) and 341 s (3D, 300 dof)
of wall time at load 8-9, 100 s of CPU together, and 330 MB. The n = 100 trees are therefore marked ``slow``
(``python -m pytest -m slow tests/test_reference_forward.py`` runs them); the default run checks n = 10 and
20 in 2D and 3D.

**Error model** (tests/test_derivatives_reference.py's, of a backward-stable solve): relative to the largest
entry of each matrix, ``K eps cond(M) dof``, ``cond`` the infinity-norm condition number from the reference's
own ``M`` and ``M^-1`` (50 digits, so the bound takes nothing from the code under test). The check can fail:
a mass changed by 1e-9 relative in the code under test's mechanism is caught (:func:`test_a_changed_mass_is_caught`).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, K

from exo_bench import prepare
from exo_bench.lagrange import derivative_reference as dr
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import random_tree

NAMES = ("qdd", "dqdd_dq", "dqdd_dqd", "Minv")


def _bound(mech, q, qd, ref) -> float:
    """``K eps cond(M) dof`` (module docstring), ``M`` the 50-digit reference's at ``(q, qd, qdd)``."""
    M = dr.inverse_derivatives(mech, q, qd, ref[0])[2]
    cond = max(np.linalg.norm(a, np.inf) * np.linalg.norm(b, np.inf) for a, b in zip(M, ref[3]))
    return K * EPS * cond * mech.dof


def _errors(mech, q, qd, tau):
    """Each output's error relative to its largest reference entry, and the bound."""
    ours = prepare(mech, "newton-euler").derivatives.forward_dynamics(q, qd, tau)
    ref = dr.forward_derivatives(mech, q, qd, tau)
    errs = {n: dr.max_relative_error(np.atleast_3d(a), np.atleast_3d(b)) for n, a, b in zip(NAMES, ours, ref)}
    return errs, _bound(mech, q, qd, ref)


def _case(n: int, dim: int, seed: int):
    mech = random_tree(n, dim, seed)
    assert -1 in mech.sign and len(set(mech.parent)) > 2, "a tree with branch signs"
    q, qd, qdd = random_states(mech, 1, seed)
    tau = prepare(mech, "newton-euler").inverse_dynamics(q, qd, qdd)
    return mech, q, qd, tau


def _check(n: int, dim: int, seed: int) -> None:
    mech, q, qd, tau = _case(n, dim, seed)
    errs, bound = _errors(mech, q, qd, tau)
    for name, err in errs.items():
        assert err <= bound, f"{mech.name} {name}: {err:.2e} > K eps cond(M) dof = {bound:.2e}"


@pytest.mark.parametrize("n, dim, seed", [(10, 2, 110), (10, 3, 111), (20, 2, 120), (20, 3, 121)])
def test_forward_derivatives_agree_with_the_50_digit_reference(n, dim, seed):
    _check(n, dim, seed)


@pytest.mark.slow
@pytest.mark.parametrize("dim, seed", [(2, 202), (3, 203)])
def test_forward_derivatives_agree_with_the_50_digit_reference_at_n_100(dim, seed):
    """The done-when's n = 100 (minutes of 50-digit arithmetic: the module docstring; so ``slow``)."""
    _check(100, dim, seed)


def test_a_changed_mass_is_caught():
    """The agreement can fail: the code under test run on a mechanism whose one mass differs by 1e-9
    relative lands outside the bound on a 3D tree of 10 links."""
    mech, q, qd, tau = _case(10, 3, 111)
    masses = [list(x) for x in mech.masses]
    masses[3][1] *= 1 + 1e-9
    bent = mech.replace(masses=tuple(tuple(x) for x in masses))
    ours = prepare(bent, "newton-euler").derivatives.forward_dynamics(q, qd, tau)
    ref = dr.forward_derivatives(mech, q, qd, tau)
    bound = _bound(mech, q, qd, ref)
    assert max(dr.max_relative_error(np.atleast_3d(a), np.atleast_3d(b)) for a, b in zip(ours, ref)) > bound
