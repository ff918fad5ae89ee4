"""The agreement bound of tests/conftest.py is tight enough to catch a 1e-12 relative error in any
single closed-form element.

Each element ``(i, j)`` of each closed form of :mod:`exo_bench.matrix_method.closed_forms.planar` (2D) and each corrected
transition of :mod:`exo_bench.matrix_method.closed_forms.transitions` (3D) is multiplied by ``1 + 1e-12`` in turn (through the
tables ``PAIRS`` / ``GRAVITY`` that the matrix method reads), and the forces of method ``matrix``
must then fail the agreement check against Pinocchio that the unperturbed forces pass. Elements that
are zero at every state (on the diagonal, the dot products of orthogonal derivatives of ``u_i``,
such as ``u_i . u_phi_i``; ``P_phi`` in 3D, which is ``0 * nu``) cannot be perturbed relatively; the
test checks that exactly those are zero.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import K, assert_forces_agree

from exo_bench import prepare
from exo_bench.matrix_method.closed_forms import planar, transitions as spatial
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.motion import random_states

REL = 1e-12


def _mechanism(dim: int) -> Mechanism:
    """A 3-link chain with a reversed middle link: every pair of links is related, so no element
    vanishes for want of a common mass, and the sign products are exercised. The tip is the
    heaviest link, so that the elements it couples to the root carry a term comparable to the
    root's row scale."""
    return Mechanism(
        dim=dim,
        g=9.81,
        parent=(-1, 0, 1),
        sign=(1, -1, 1),
        masses=((0.3, 0.5, 0.4), (0.2, 0.9, 0.5), (0.4, 1.6, 1.8)),
        n=(0.4, 0.55, 0.35),
        name=f"sensitivity-{dim}d",
    )


class _Module:
    """A module's functions seen as a table, so that every closed form is swapped the same way."""

    def __init__(self, module):
        self.module = module

    def __getitem__(self, key):
        return getattr(self.module, key)

    def __setitem__(self, key, value):
        setattr(self.module, key, value)


def _perturb(f, index):
    def g(*args):
        out = np.array(f(*args), dtype=float)  # a copy: the closed form's own array is untouched
        out[(Ellipsis,) + index] *= 1.0 + REL
        return out

    return g


def _cases(dim):
    n = 3
    pairs, gravity = (planar.PAIRS, planar.GRAVITY) if dim == 2 else (spatial.PAIRS, spatial.GRAVITY)
    for block, fns in pairs.items():
        for name in fns:
            # 3D D_l = -(H_phi)^T is called by name (it takes the transposed 3D H_phi, not the namespace)
            table, key = (_Module(spatial), "d_l") if (dim, block, name) == (3, "l", "D") else (pairs[block], name)
            for i in range(n):
                for j in range(n):
                    yield table, key, (i, j), f"{block}.{name}[{i},{j}]"
    for block in gravity:
        for i in range(n):
            yield gravity, block, (i,), f"{block}.P[{i}]"


def _element_is_zero(model, q, table, key, index) -> bool:
    """Whether the element is zero at every state, exactly or up to the rounding of a difference of
    equal products (below ``eps`` times the largest element of its matrix): then a relative change
    changes nothing measurable, and nothing physical."""
    seen = []
    original = table[key]

    def spy(*args):
        out = np.asarray(original(*args), dtype=float)
        seen.append((out[(Ellipsis,) + index], np.abs(out).max()))
        return out

    table[key] = spy
    try:
        model.matrices(q)
    finally:
        table[key] = original
    assert seen, f"{key} was never called"
    return all(np.abs(x).max() <= np.finfo(float).eps * top for x, top in seen)


@pytest.mark.parametrize("dim", [2, 3])
def test_a_1e12_change_of_any_single_closed_form_element_fails_the_agreement_check(dim):
    mech = _mechanism(dim)
    q, qd, qdd = random_states(mech, 40, seed=11)
    ref = prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)
    model = prepare(
        mech, "matrix", kernel="numpy"
    )  # the numpy reference reads the patched closed forms; the numba kernels compiled them
    assert assert_forces_agree(model.inverse_dynamics(q, qd, qdd), ref, mech, q, qd, qdd) <= K
    detected, zero, missed = [], [], []
    for table, key, index, label in _cases(dim):
        if _element_is_zero(model, q, table, key, index):
            zero.append(label)
            continue
        original = table[key]
        table[key] = _perturb(original, index)
        try:
            tau = model.inverse_dynamics(q, qd, qdd)
        finally:
            table[key] = original
        try:
            assert_forces_agree(tau, ref, mech, q, qd, qdd)
        except AssertionError:
            detected.append(label)
        else:
            missed.append(label)
    assert not missed, f"a {REL:g} relative change of these elements passes the agreement check: {missed}"
    expected_zero = {
        f"{b}.{x}[{i},{i}]" for b, x in [("phi", "Lambda"), ("phi", "D"), ("l", "A"), ("l", "H")] for i in range(3)
    }
    if dim == 3:  # diagonal: the derivative vectors of u_i that are orthogonal (u . u_phi = 0, ...)
        orthogonal = {"phi": "B Lambda D E K", "psi": "A Lambda E G H", "l": "A B G H K"}
        expected_zero = {f"{b}.{x}[{i},{i}]" for b, xs in orthogonal.items() for x in xs.split() for i in range(3)} | {
            f"phi.P[{i}]" for i in range(3)
        }  # gravity does no work on an azimuth
    assert set(zero) == expected_zero, (sorted(set(zero) - expected_zero), sorted(expected_zero - set(zero)))
    assert len(detected) + len(zero) == len(list(_cases(dim)))
