"""The printed formulas as encoded: hand-derived facts about each misprint, and the corrections."""

import numpy as np
import pytest
from conftest import K, assert_close, matrix_scale, term_scale

from exo_bench.matrix_method import printed
from exo_bench.bench.studies.errata import pinocchio_matrices
from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, fig1, fig5, random_tree

BY_KEY = {f.key: f for f in printed.ALL}


def _transition_inputs(m, seed):
    q, _, _ = random_states(m, 10, seed)
    m2 = m.replace(dim=2)
    q2 = np.concatenate([q[:, : m.nlinks], q[:, 2 * m.nlinks :]], axis=1)
    spatial = pinocchio_matrices(m, q)
    t = printed.transition_namespace(m, q, pinocchio_matrices(m2, q2), three_d=spatial)
    return q, t, spatial


def _quotient_scale(mech, q):
    """:func:`conftest.matrix_scale` for lines that divide: a quotient times its divisor again loses
    ``eps / |divisor|`` relative, so the bound grows by ``1 / min |divisor|`` per sample (divisors
    of (18): ``cos(phi_i - phi_j)``, ``cos phi_i``, ``sin phi_i``, ``l_j``)."""
    n = mech.nlinks
    phi, l = q[:, :n], q[:, -n:]
    divisor = np.minimum.reduce(
        [
            np.abs(np.cos(phi[:, :, None] - phi[:, None, :])).min(axis=(1, 2)),
            np.abs(np.cos(phi)).min(axis=1),
            np.abs(np.sin(phi)).min(axis=1),
            l.min(axis=1),
        ]
    )
    return matrix_scale(mech, q) / np.minimum(1.0, divisor)[:, None, None]


def test_printed_eq14_has_phi_dot_where_psi_dot_belongs(rel):
    """Printed (14) minus the true M_psi is 2 zeta l l' (phi' - psi'), and nothing else."""
    m = fig1(3)
    q, qd, qdd = random_states(m, 30, 1)
    x = printed.equation_namespace(m, q, qd, qdd)
    zeta = x.zeta(1)
    true = pb.inverse_dynamics(m, q, qd, qdd)[:, 1]
    diff = BY_KEY["14"].fn(x)[:, 0] - true
    scale = term_scale(m, q, qd, qdd)[:, 1]
    assert_close(diff, 2 * zeta * x.l(1) * x.dl(1) * (x.dphi(1) - x.dpsi(1)), scale, k=2 * K)  # two sides rounded
    assert_close(BY_KEY["14"].corrected(x)[:, 0], true, scale)


@pytest.mark.parametrize("mech", [random_tree(4, 3, 1), exo5(3)], ids=lambda m: m.name)
def test_printed_g_l_carries_a_spurious_cos_psi_i_cos_psi_j(mech):
    """With 3D a^l = 2D a^l cos psi_i cos psi_j on its right side, printed g^l is the true G_l times
    cos psi_i cos psi_j."""
    q, t, spatial = _transition_inputs(mech, 2)
    scale = _quotient_scale(mech, q)
    true = spatial["l"]["G"]
    value = BY_KEY["18:g^l"].fn(t)
    assert_close(value, true * t.cos_psi_i * t.cos_psi_j, scale)
    assert np.abs(value - true).max() > 1e-2 * np.abs(true).max()
    assert_close(BY_KEY["18:g^l"].corrected(t), true, scale)


@pytest.mark.parametrize("mech", [random_tree(4, 3, 3), fig5(3)], ids=lambda m: m.name)
def test_printed_k_l_has_the_wrong_sign(mech):
    q, t, spatial = _transition_inputs(mech, 4)
    scale = _quotient_scale(mech, q)
    true = spatial["l"]["K"]
    assert np.abs(true).max() > 1e-2
    assert_close(BY_KEY["18:k^l"].fn(t), -true, scale)
    assert_close(BY_KEY["18:k^l"].corrected(t), true, scale)


def test_the_line_labelled_2d_k_psi_is_the_3d_k_psi():
    m = random_tree(4, 3, 5)
    q, t, spatial = _transition_inputs(m, 6)
    f = BY_KEY["18:k^psi"]
    assert f.printed_dim == 2 and "psi" not in pinocchio_matrices(m.replace(dim=2), np.zeros((1, 8)) + 0.5)
    assert_close(f.fn(t), spatial["psi"]["K"], _quotient_scale(m, q))


@pytest.mark.parametrize("mech", [random_tree(5, 3, 7), exo5(3)], ids=lambda m: m.name)
def test_every_other_line_of_eq18_holds_as_printed(mech):
    q, t, spatial = _transition_inputs(mech, 8)
    scale = _quotient_scale(mech, q)
    for f in printed.TRANSITIONS:
        if f.fn is None or f.key in ("18:g^l", "18:k^l"):
            continue
        ref = spatial[f.block][f.name]
        value = np.broadcast_to(f.fn(t), ref.shape)
        sc = np.diagonal(scale, axis1=1, axis2=2) if f.name == "P" else scale
        assert_close(value, ref, sc, what=f.key)


def test_only_the_exactly_one_index_reading_of_the_branch_rule_matches_fig5():
    """Section 5's rule applied to Fig. 5's links as an unreversed chain gives Fig. 5 only when an
    element changes sign with exactly one index after the branch point (= s_i s_j)."""
    branched = fig5(2)
    chain_like = branched.replace(sign=(1, 1, 1, 1))
    q, _, _ = random_states(branched, 5, 9)
    a, b = pinocchio_matrices(chain_like, q), pinocchio_matrices(branched, q)
    scale = matrix_scale(branched, q)
    verdict = {}
    for reading, sigma in printed.branch_sign_readings(3, 4).items():
        verdict[reading] = all(
            np.abs(sigma * a[blk][k] - b[blk][k]).max() <= K * np.finfo(float).eps * scale.max()
            for blk in b
            for k in b[blk]
            if k != "P"
        )
    assert verdict == {
        "either index after the branch point": False,
        "both indices after the branch point": False,
        "exactly one index after the branch point": True,
    }
    assert np.array_equal(
        printed.branch_sign_readings(3, 4)["exactly one index after the branch point"],
        np.outer(branched.sign, branched.sign),
    )
