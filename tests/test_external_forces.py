"""External forces at the point masses (``f_ext``, issue 37): the generalised force ``Q = sum_k J_k^T f_k``
against a hand-derived one-link case, virtual work, complex-step derivatives, and every method's
inverse and forward dynamics on seeded random trees (the engines' own ``fext``, ``xfrc_applied`` and
applied spatial forces: tests/test_external_forces_engines.py).

Error model: ``Q`` adds to row ``a`` the terms ``lever_a c_ak e . f_k`` (one per point ``k`` on or
beyond rod ``a`` and component, each a product of at most four rounded factors): their magnitudes
sum to :func:`external_force_scale`, which is added to :func:`conftest.term_scale`, with the same
``K``."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, K, assert_close, term_scale

from exo_bench import prepare
from exo_bench.models.runtime import external_forces as xf
from exo_bench.models.runtime import external_forces as xc
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.mechanism.presets import fig1, random_tree


def external_force_scale(mech, q, f_ext) -> np.ndarray:
    """``(S, dof)``: row ``a`` of link ``i`` bounds ``sum |terms|`` of ``Q_a``: the lever ``|r_a|`` (``l_i``
    for an angle, 1 for a length) times ``sum_k c_ik |f_k|_1`` over the points on or beyond rod ``i``
    (``c = 1`` beyond, the fraction on rod ``i``), times ``max(1, |angles|)``; joint moments (Pinocchio's
    angle rows) sum their subtree rows, as in conftest.term_scale."""
    from conftest import _lever_arms, _link_of_row, _subtree_rows

    q = np.atleast_2d(q)
    f = np.abs(np.asarray(f_ext, float)).sum(axis=-1).reshape(q.shape[0], mech.nlinks, 3)  # |f_k|_1
    n = mech.nlinks
    own = (f * mech.fractions[None]).sum(axis=2)
    through = f.sum(axis=2)
    per_link = own.copy()
    for i in range(n):
        for a in mech.ancestors[i]:
            per_link[:, a] += through[:, i]
    angles = np.maximum(1.0, np.abs(q[:, :-n]).max(axis=1, initial=0.0))[:, None]
    rows = _lever_arms(mech, q) * per_link[:, _link_of_row(mech)] * angles
    return rows @ _subtree_rows(mech).T


def _case(mech, seed: int, samples: int = 4):
    rng = np.random.default_rng(seed)
    n, d = mech.nlinks, mech.dim
    q = rng.uniform(-1.2, 1.2, (samples, mech.dof))
    q[:, -n:] = rng.uniform(0.3, 1.5, (samples, n))
    qd, qdd = rng.normal(size=(2, samples, mech.dof))
    f = rng.normal(scale=40.0, size=(samples, n, 3, d))
    return q, qd, qdd, f


TREES = [random_tree(5, d, seed) for d in (2, 3) for seed in (1, 2)]


def test_one_link_by_hand():
    """fig1, 2D: a force ``F`` at the end (fraction 1) and ``G`` at the middle (fraction n) give
    ``Q_phi = l (cos phi (Fy + n Gy) - sin phi (Fx + n Gx))``, ``Q_l = cos phi (Fx + n Gx) + sin phi (Fy + n Gy)``."""
    mech = fig1(2)
    phi, l, n = 0.7, 0.45, mech.n[0]
    F, G = np.array([3.0, -5.0]), np.array([-2.0, 7.0])
    f = np.zeros((1, 3, 2))
    f[0, 2], f[0, 1] = F, G
    H = F + n * G
    c, s = np.cos(phi), np.sin(phi)
    want = np.array([l * (c * H[1] - s * H[0]), c * H[0] + s * H[1]])
    q = np.array([phi, l])
    assert_close(xf.generalized_forces(mech, q[None], f[None])[0], want, np.abs(want).sum() * 4, K, "Q")
    model = prepare(mech, "newton-euler")
    qd, qdd = np.array([0.3, -0.2]), np.array([1.0, 2.0])
    free = model.inverse_dynamics(q, qd, qdd)
    got = model.inverse_dynamics(q, qd, qdd, f_ext=f)
    assert got.shape == (2,)
    assert_close(got, free - want, term_scale(mech, q, qd, qdd)[0] + np.abs(want).sum() * 4, K, "ID with f_ext")


def test_start_force_of_a_root_does_nothing_and_weight_is_cancelled():
    """A force at a root's start (the support O) does no work; forces ``m_k g up`` at every point mass
    cancel gravity: a resting tree stays at rest (qdd = 0)."""
    mech = TREES[2]
    q, _, _, _ = _case(mech, 3, 1)
    f = np.zeros((1, mech.nlinks, 3, mech.dim))
    for i, p in enumerate(mech.parent):
        if p < 0:
            f[0, i, 0, 0] = 1e3
    assert np.abs(xf.generalized_forces(mech, q, f)).max() == 0.0
    f[...] = 0.0
    f[0, :, :, -1] = mech.mass_array * mech.g
    model = prepare(mech, "newton-euler")
    qdd = model.forward_dynamics(q, np.zeros_like(q), np.zeros_like(q), f_ext=f)
    M = model.mass_matrix(q)[0]
    assert np.abs(M @ qdd[0]).max() <= K * EPS * term_scale(mech, q).max()


@pytest.mark.parametrize("mech", TREES, ids=lambda m: m.name)
def test_virtual_work(mech):
    """``Q . qd = sum_k f_k . P_k'`` with the points' velocities from models/mechanism/kinematics.py (the
    geometry alone), on seeded random trees."""
    q, qd, _, f = _case(mech, 11)
    Q = xf.generalized_forces(mech, q, f)
    power = np.einsum("sikd,sikd->s", f, point_mass_velocities(mech, q, qd))
    scale = (external_force_scale(mech, q, f) * np.abs(qd)).sum(axis=1)
    assert_close((Q * qd).sum(axis=1), power, scale, K, "Q . qd against the power")  # measured 0.27


@pytest.mark.parametrize("mech", TREES, ids=lambda m: m.name)
def test_dQ_dq_by_complex_step(mech):
    """``dQ/dq`` (a rod's block only: the forces are fixed in the world) against the complex-step
    derivative of ``Q``, exact to rounding."""
    q, _, _, f = _case(mech, 5, 2)
    D = xf.dQ_dq(mech, q, f)
    h = 1e-30
    for a in range(mech.dof):
        z = q.astype(complex)
        z[:, a] += 1j * h
        col = xf.generalized_forces(mech, z, f.astype(complex)).imag / h
        assert_close(D[:, :, a], col, external_force_scale(mech, q, f), K, f"column {a}")


@pytest.mark.parametrize("mech", TREES, ids=lambda m: m.name)
def test_positions_move_as_q_says(mech):
    """Q is the gradient of the work ``sum_k f_k . P_k(q)``: central differences of the positions."""
    q, _, _, f = _case(mech, 8, 1)
    h = 1e-6
    grad = np.empty(mech.dof)
    for a in range(mech.dof):
        e = np.zeros_like(q)
        e[0, a] = h
        grad[a] = (np.sum(f * point_mass_positions(mech, q + e)) - np.sum(f * point_mass_positions(mech, q - e))) / (
            2 * h
        )
    Q = xf.generalized_forces(mech, q, f)[0]
    assert np.abs(Q - grad).max() <= 1e-7 * np.abs(f).sum()  # h^2 truncation and eps / h rounding


def test_compiled_equals_numpy():
    for mech in TREES:
        q, _, _, f = _case(mech, 4, 3)
        assert np.array_equal(xf.generalized_forces(mech, q, f), xc.generalized_forces_compiled(mech, q, f))
