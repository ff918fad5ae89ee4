"""Forward-dynamics derivatives without dense LU (issue 36): ``model.derivatives.forward_dynamics``.

``dqdd/dq = -M^-1 dID/dq``, ``dqdd/dqd = -M^-1 dID/dqd``, ``dqdd/dtau = M^-1`` at ``qdd = FD(q, qd, tau)``,
with ``M^-1`` applied column by column by the O(n) forward dynamics (models/newton_euler/forward_jacobians.py).

Oracles and error models:

* **CasADi's path** (matrix_method/derivatives.py: AD of the factored closed forms and an equilibrated LU
  of ``M``), the issue's criterion: 1e-13 relative to the largest entry of each sample's matrix, on
  well-conditioned states (``cond(M) <= 1e3``: a solve loses ``cond(M)`` ulps, so two solves agree to about
  ``cond(M) eps``, 2e-13 at the bound; the seeded states below stay under 1e2).
* **Complex step of the numpy forward dynamics** (:func:`exo_bench.models.newton_euler.passes.forward_dynamics`
  on complex states, ``h = 1e-30``: no subtraction, truncation ``h^2 f''' / 6`` below 1e-58). Both sides are
  float64 evaluations of ``X = M^-1 B``; perturbation theory of a linear system gives ``|dX| <= cond(M)
  (|dM| / |M| |X| + |M^-1| |dB|)`` with ``|dM| <= K eps |M|`` and ``|dB| <= K eps D``, ``D = 2 S / min(l, 1)``
  the scale of the differentiated terms (``S`` conftest's term scale), per sample in 2-norms, times 2 for the
  two sides: the model of tests/test_casadi.py's forward test.
* **M^-1 M = I** to the conditioning bound ``|M^-1 M - I| <= 2 K eps cond(M) sqrt(dof)`` (a backward-stable
  solve of each column; the product adds ``K eps |M^-1| |M|``, the same order).
* **No dense LU, O(n^2)**: the call runs with ``numpy.linalg`` removed, and the compiled kernel's work is
  counted: one O(n) pass per column, ``3 dof`` columns per sample.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_derivatives_analytic import states

from conftest import EPS, K, term_scale
from exo_bench import prepare, presets
from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.runtime.conditioning import NumericallySingularError
from exo_bench.models.derivatives import Derivatives
from exo_bench.models.newton_euler import forward_jacobians, passes
from exo_bench.models.newton_euler.passes import prepare_tree
from exo_bench.models.mechanism.presets import random_tree
from exo_bench.models.mechanism.singularity import SingularConfigurationError

TREES = [random_tree(5, 2, 11), random_tree(6, 3, 12), presets.exo5(dim=3), presets.exo5(dim=2), random_tree(7, 3, 4)]
IDS = [m.name for m in TREES]
H = 1e-30


def _case(mech, samples=5, seed=8):
    """test_derivatives_analytic's seeded states moved away from the singular ones: elevations within 0.8
    rad, lengths in [0.6, 1.4] (``cond(M)`` then stays within the mass distribution's own, below 1e3 on these
    trees), and ``tau = ID(q, qd, qdd)``."""
    q, qd, qdd = states(mech, samples, seed)
    n = mech.nlinks
    if mech.dim == 3:
        q[:, n : 2 * n] *= 0.8 / 1.2
    q[:, -n:] = 0.6 + (q[:, -n:] - 0.3) * (0.8 / 1.2)
    tau = prepare(mech, "newton-euler").inverse_dynamics(q, qd, qdd)
    return q, qd, tau


def _mass(mech, q):
    return passes.mass_matrix(prepare_tree(mech), mech.dim, coupling(mech), q)


def _rel(a, b) -> np.ndarray:
    """Per sample, the largest difference relative to the largest entry of the reference."""
    ax = tuple(range(1, a.ndim))
    return np.abs(a - b).max(axis=ax) / np.abs(b).max(axis=ax)


@pytest.mark.parametrize("kernel", ["numba", "numpy"])
@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_forward_derivatives_equal_casadis_path(mech, kernel):
    """The analytic forward-dynamics derivatives equal CasADi's (today's path) to 1e-13 relative per
    sample, on states whose ``cond(M)`` stays below 1e3 (module docstring)."""
    pytest.importorskip("casadi")
    from exo_bench.matrix_method.derivatives import derivatives_of

    q, qd, tau = _case(mech)
    assert (np.linalg.cond(_mass(mech, q)) <= 1e3).all()  # the criterion's premise
    ours = Derivatives(mech, kernel=kernel).forward_dynamics(q, qd, tau)
    ref = derivatives_of(mech, "matrix-factored").forward_dynamics(q, qd, tau)
    for name, a, b in zip(("qdd", "dqdd_dq", "dqdd_dqd", "Minv"), ours, ref):
        assert (_rel(a, b) <= 1e-13).all(), f"{name}: {_rel(a, b).max():.3g}"


def _complex_step(mech, q, qd, tau):
    tree, dim, g, d = prepare_tree(mech), mech.dim, float(mech.g), mech.dof
    out = np.empty((3, q.shape[0], d, d))
    z = lambda x: x.astype(complex)  # noqa: E731
    for k in range(d):
        e = np.zeros(q.shape, dtype=complex)
        e[:, k] = 1j * H
        for i, (a, b, c) in enumerate(((q + e, z(qd), z(tau)), (z(q), qd + e, z(tau)), (z(q), z(qd), tau + e))):
            out[i][:, :, k] = passes.forward_dynamics(tree, dim, g, a, b, c).imag / H
    return out


@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_forward_derivatives_against_complex_step_of_the_numpy_forward_dynamics(mech):
    """dqdd/dq, dqdd/dqd and M^-1 against a complex step of the O(n) numpy forward dynamics, within the
    perturbation bound of the module docstring (which is checked to mean something: below 1e-9 of the
    Jacobian's norm)."""
    q, qd, tau = _case(mech)
    _, jq, jqd, Minv = prepare(mech, "newton-euler").derivatives.forward_dynamics(q, qd, tau)
    cs = _complex_step(mech, q, qd, tau)
    M = _mass(mech, q)
    cond, minv, d, n = np.linalg.cond(M), np.linalg.norm(Minv, 2, axis=(1, 2)), mech.dof, mech.nlinks
    a = Derivatives(mech).forward_dynamics(q, qd, tau)[0]
    S = term_scale(mech, q, qd, a).max(axis=1) * 2 / np.minimum(q[:, -n:], 1.0).min(axis=1)
    for name, X, ref in (("dqdd_dq", jq, cs[0]), ("dqdd_dqd", jqd, cs[1]), ("Minv", Minv, cs[2])):
        Xn = np.linalg.norm(ref, 2, axis=(1, 2))
        bound = 2 * K * EPS * (cond * Xn + minv * S * math.sqrt(d))
        err = np.linalg.norm(X - ref, 2, axis=(1, 2))
        assert (err <= bound).all(), f"{name}: {(err / bound).max():.3g} x the bound"
        assert (bound <= 1e-9 * Xn).all(), f"{name}: the bound would not test anything"


@pytest.mark.parametrize("mech", TREES, ids=IDS)
def test_inverse_mass_times_mass_is_the_identity(mech):
    """``M^-1 M = I`` to ``2 K eps cond(M) sqrt(dof)`` per sample, for the compiled and the numpy kernel,
    and the compiled ``M^-1``, ``dqdd/dq`` and ``dqdd/dqd`` equal the numpy reference to the same bound
    relative to their norms."""
    q, qd, tau = _case(mech, samples=6, seed=3)
    M = _mass(mech, q)
    bound = 2 * K * EPS * np.linalg.cond(M) * math.sqrt(mech.dof)
    eye = np.broadcast_to(np.eye(mech.dof), M.shape)
    both = [Derivatives(mech, kernel=k).forward_dynamics(q, qd, tau) for k in ("numba", "numpy")]
    minvs = [x[3] for x in both]
    for a, b in zip(both[0][1:3], both[1][1:3]):  # the compiled Jacobians and the numpy reference
        norm = np.linalg.norm(b, 2, axis=(1, 2))
        assert (np.linalg.norm(a - b, 2, axis=(1, 2)) <= bound * norm).all()
    for Minv in minvs:
        assert (np.linalg.norm(Minv @ M - eye, 2, axis=(1, 2)) <= bound).all()
    assert (
        np.linalg.norm(minvs[0] - minvs[1], 2, axis=(1, 2)) <= bound * np.linalg.norm(minvs[1], 2, axis=(1, 2))
    ).all()


def test_no_dense_solve_and_one_pass_per_column(monkeypatch):
    """The forward-dynamics derivatives use no dense LU (``numpy.linalg`` raises if called) and the
    compiled kernel solves ``3 dof`` columns per sample with the O(n) passes: counted by the columns
    it is handed, so the work is ``3 dof`` passes of O(n) each, O(n^2), the size of the output. The public
    call runs the same kernels in one compiled call (``forward_derivatives``), which no count from Python
    sees: the count is of its steps one after another, which give the same bits."""
    mech = random_tree(8, 3, 5)
    q, qd, tau = _case(mech, samples=3)
    D = Derivatives(mech, kernel="numba")
    fused = D.forward_dynamics(q, qd, tau)  # compile outside the count
    D._fused_forward = False  # the kernels one after another, from Python
    for a, b in zip(D.forward_dynamics(q, qd, tau), fused):
        np.testing.assert_array_equal(a, b)

    def refuse(*a, **k):
        raise AssertionError("a dense solve")

    for name in ("solve", "inv", "lstsq", "cholesky"):
        monkeypatch.setattr(np.linalg, name, refuse)
    handed = []
    real = forward_jacobians.columns

    class Counting:
        def __call__(self, t, dim, X, B, O):
            handed.append(B.shape)
            return real(t, dim, X, B, O)

    monkeypatch.setattr(forward_jacobians, "columns", Counting())
    monkeypatch.setattr(forward_jacobians, "columns_parallel", Counting())
    D.forward_dynamics(q, qd, tau)
    assert handed == [(3, mech.dof, mech.dof)]  # M^-1: dof columns, the rest O(n^2) products with blocks


@pytest.mark.parametrize(
    "what, link",
    [("l", 4), ("psi", 2)],
)
def test_singular_states_refuse_in_every_forward_derivative_call_naming_the_link(what, link):
    """A rod of length zero or (3D) a vertical rod: the full Jacobians, the JVP and the VJP of forward
    dynamics refuse with forward dynamics' own message, naming the link; never NaN."""
    mech = presets.exo5(dim=3)
    n = mech.nlinks
    q, qd, tau = _case(mech, samples=2)
    if what == "l":
        q[1, 2 * n + link] = 0.0
    else:
        q[1, n + link] = math.pi / 2
    model = prepare(mech, "newton-euler")
    with pytest.raises(SingularConfigurationError) as want:
        model.forward_dynamics(q, qd, tau)
    assert f"link {link + 1}" in str(want.value)
    D = model.derivatives
    calls = (
        lambda: D.forward_dynamics(q, qd, tau),
        lambda: D.forward_dynamics_jvp(q, qd, tau, qd, qd, tau),
        lambda: D.forward_dynamics_vjp(q, qd, tau, tau),
    )
    for call in calls:
        with pytest.raises(SingularConfigurationError) as got:
            call()
        assert str(got.value) == str(want.value)


def test_ill_conditioned_states_refuse():
    """A rod within 1e-9 rad of vertical is beyond the conditioning bound: NumericallySingularError, as
    forward dynamics raises, in the full and the directional forward derivatives."""
    mech = presets.exo5(dim=3)
    q, qd, tau = _case(mech, samples=1)
    q[0, mech.nlinks + 2] = math.pi / 2 - 1e-9
    model = prepare(mech, "newton-euler")
    with pytest.raises(NumericallySingularError):
        model.forward_dynamics(q, qd, tau)
    D = model.derivatives
    for call in (lambda: D.forward_dynamics(q, qd, tau), lambda: D.forward_dynamics_vjp(q, qd, tau, tau)):
        with pytest.raises(NumericallySingularError):
            call()
