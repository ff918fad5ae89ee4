"""Forward dynamics inverts inverse dynamics on every method (hypothesis, the mechanisms and states of
tests/test_properties.py: trees of 1 to 5 links, several roots, signs, zero masses, near-vertical
and exactly vertical rods, zero and tiny lengths, 2D and 3D).

**Error model.** ``tau = ID(q, qd, qdd)`` carries at most ``K eps S(q, qd, qdd)`` per row
(conftest.term_scale); forward dynamics computes ``h`` (``K eps S(q, qd, 0)``) and ``M`` (``K eps
S_M``, conftest.mass_matrix_scale with ``derived=True``: the methods that derive ``M`` from inverse
dynamics subtract the gravity forces) and solves ``M qdd = tau - h`` by a backward-stable
factorisation (Cholesky of the equilibrated ``M``; newton-euler: ``J^-1 mu^-1 J^-T``, each factor
stable). A perturbation ``d`` of the right-hand side or ``dM`` of ``M`` moves the solution by
``M^-1 (d - dM qdd)``, so

    |qdd' - qdd|_2 <= k eps |M^-1|_2 ( |S(q, qd, qdd)|_2 + |S(q, qd, 0)|_2 + |S_M|_2 |qdd|_2 )

with ``k = K`` (8 roundings of each term), i.e. ``k eps cond(M)`` relative to ``|M| |qdd|``.
``|M^-1|_2`` is the exact-arithmetic ``1 / sigma_min`` of Pinocchio's ``M`` (CRBA) where it is
resolved; where rounding hides ``sigma_min`` (rods of 1e-9 m near vertical) the bound is vacuous
and only finiteness is asserted. Where :func:`exo_bench.models.mechanism.singularity.singular_reasons` names a cause,
every method raises :class:`SingularConfigurationError` with that reason instead (a singular ``mu``:
newton-euler names the link whose pivot of ``M_r`` vanished, in its own words); where the conditioning
test that every method shares (:mod:`exo_bench.models.runtime.conditioning`) is beyond its bound, every method
refuses it as numerically singular.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS, K, mass_matrix_scale, term_scale
from hypothesis import event, example, given
from test_properties import CHAIN3, EXAMPLE_RATES, PROFILE, VERTICAL, cases

from exo_bench import prepare
from exo_bench.models.runtime.conditioning import conditioning_reasons, coupling_condition
from exo_bench.models.mechanism.singularity import SingularConfigurationError, singular_reasons

LAGRANGE_MAX_LINKS = 2


def _models(mech):
    names = ["pinocchio", "matrix", "matrix-factored", "recurrence"]
    out = {name: prepare(mech, name) for name in names}
    out["newton-euler (numba)"] = prepare(mech, "newton-euler")
    out["newton-euler (numpy)"] = prepare(mech, "newton-euler", kernel="numpy")
    if mech.dim == 2:  # eq. (18) as printed only matters in 3D: in 2D it is the closed forms
        out["matrix-paper"] = prepare(mech, "matrix-paper")
    if mech.nlinks <= LAGRANGE_MAX_LINKS:
        out["lagrange"] = prepare(mech, "lagrange")
    return out


REGULAR = (np.array([[0.3, -2.0, 1.1, 0.2, -0.4, 0.2, 1.0, 0.5, 0.7]]), EXAMPLE_RATES, -EXAMPLE_RATES)


@PROFILE
@given(cases())
@example((CHAIN3, VERTICAL, EXAMPLE_RATES, -EXAMPLE_RATES))
@example((CHAIN3.replace(masses=((1.0, 1.0, 1.0),) * 3), *REGULAR))
def test_forward_dynamics_inverts_inverse_dynamics_on_every_method(case):
    mech, q, qd, qdd = case
    reasons = singular_reasons(mech, q)
    singular = np.array([bool(r) for r in reasons])
    M = prepare(mech, "pinocchio").mass_matrix(q)
    scale = (
        np.linalg.norm(term_scale(mech, q, qd, qdd), axis=1)
        + np.linalg.norm(term_scale(mech, q, qd), axis=1)
        + np.linalg.norm(mass_matrix_scale(mech, q, derived=True), ord=2, axis=(1, 2)) * np.linalg.norm(qdd, axis=1)
    )
    sigma = np.linalg.svd(M, compute_uv=False)
    # sigma_min resolved: above the rounding of M itself (Weyl), else the bound is vacuous
    resolved = sigma[:, -1] > 2 * K * EPS * np.linalg.norm(mass_matrix_scale(mech, q, derived=True), ord=2, axis=(1, 2))
    coupling = coupling_condition(mech)
    beyond = np.array([bool(conditioning_reasons(mech, q[s : s + 1], coupling)) for s in range(q.shape[0])])
    event("singular" if singular.any() else "beyond the conditioning bound" if beyond.any() else "regular")
    for name, model in _models(mech).items():
        tau = model.inverse_dynamics(q, qd, qdd)
        if singular.any():
            s = int(np.argmax(singular))
            with pytest.raises(SingularConfigurationError) as e:
                model.forward_dynamics(q[s], qd[s], tau[s])
            first = reasons[s][0]
            if "mass" in first:  # mu singular: newton-euler names the link whose pivot of M_r vanished
                assert "mass" in str(e.value), name
            else:
                assert first in str(e.value), name
        if (~singular & beyond).any():  # beyond the conditioning bound: every method refuses, named
            with pytest.raises(SingularConfigurationError, match="numerically singular|mass"):
                model.forward_dynamics(q[~singular & beyond], qd[~singular & beyond], tau[~singular & beyond])
        ok = ~singular & resolved & ~beyond
        if (~singular & ~resolved & ~beyond).any():
            # sigma_min below the rounding of M: a finite answer, or the error that names it numerically
            # singular (M derived by differences can lose a diagonal of 1e-30 entirely); never NaN
            try:
                assert np.isfinite(
                    model.forward_dynamics(
                        q[~singular & ~resolved], qd[~singular & ~resolved], tau[~singular & ~resolved]
                    )
                ).all(), name
            except SingularConfigurationError as e:
                assert "numerically singular" in str(e), name
        if not ok.any():
            continue
        got = model.forward_dynamics(q[ok], qd[ok], tau[ok])
        assert np.isfinite(got).all(), name
        err = np.linalg.norm(got - qdd[ok], axis=1)
        ratio = err * sigma[ok, -1] / (EPS * scale[ok])
        event(
            f"largest ratio {'<= 0.01' if ratio.max() <= 0.01 else '<= 0.1' if ratio.max() <= 0.1 else '<= 1' if ratio.max() <= 1 else '> 1'}"
        )
        assert (ratio <= K).all(), (name, float(ratio.max()))
