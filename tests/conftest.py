"""Shared test helpers, and THE error model of every agreement test.

Error model of agreement between float64 implementations
--------------------------------------------------------
Every generalised force is a sum of terms ``x_ij * r_j``: a mass coefficient, at most two rod
lengths, the cosines and sines of at most two angles (or an angle difference), and an
acceleration, a product of two rates, or ``g`` (eqs. 5/17; RNEA and Lagrange compute the same
terms along other paths: spatial velocities, rotations, lambdified expressions). Each term is a
product of at most ~8 rounded factors, so it carries a relative error of at most ~4 eps; an
angle ``a`` enters a sine or cosine with an absolute error of ``eps * |a|`` (angle differences,
Pinocchio's relative joint angles); and summing the terms in any order adds at most ``eps`` per
addition level times the sum of the magnitudes. Two implementations therefore differ by

    |a - b| <= k * eps * scale,    scale = (sum of |terms| of the row) * max(1, |angles|)

with a small ``k``: :data:`K` = 8, i.e. 8 roundings of ``eps / 2`` per term on each side. The
measured ratio ``|a - b| / (eps * scale)`` is at most 2.3 over every method on 100 seeded random
trees (800 states; forces and mass matrices against Pinocchio), within the bound on every
hypothesis-generated mechanism and state (tests/test_properties.py), and a 1e-12 relative change
of any single closed-form element gives a ratio of at least 10.8 (tests/test_tolerance_sensitivity.py). The former tolerance, 1e-10 relative, let a
formula error of 1e-11 pass.

:func:`term_scale` bounds the sum of ``|terms|`` of every row from the mechanism and the states
alone (no code under test: the mass coupling is recomputed from the point masses by
:func:`mass_coupling_oracle`); :func:`mass_matrix_scale` does the same for the entries of ``M``.
In Pinocchio an angle's force is a joint moment minus those of the child joints (``tau = G^T
tau_joint``), so the scale of an angle's row is that of its subtree's rows
(:func:`_subtree_rows`).

Other error models used in the tests (each stated where it is used):

* MuJoCo works in a com-based frame: its rounding has a term of its own, :func:`com_frame_scale`,
  added where one side is MuJoCo (``com_frame=True``); without it MuJoCo's mass matrices exceed
  ``K`` on some seeded trees, with it they are well within (tests/test_mujoco_drake.py::
  test_mujocos_com_frame_term_is_needed_and_enough).

* power balance (:func:`power_balance_residual`) compares with a sixth-order central difference
  of the energy, whose truncation error ``O(h^6)``, ``h = 1e-3``, and rounding error
  ``eps * |E| / h`` dominate: its bound is :data:`POWER_BALANCE_TOL`.
* derived quantities (``M`` from inverse dynamics by differences, ``M`` as the Hessian of ``T``
  by finite second differences of a quadratic) state their own extra factor.
"""

import numpy as np
import pytest
from xdist_workers import (  # noqa: F401  (conftest hooks)
    pytest_cmdline_main,
    pytest_configure,
    pytest_sessionstart,
    pytest_xdist_make_scheduler,
)

EPS = float(np.finfo(float).eps)

#: Ulps allowed per unit of term scale (see the module docstring): ~8 rounded factors per term
#: (``eps / 2`` each) on each of the two sides.
K = 8


def mass_coupling_oracle(mech) -> tuple[np.ndarray, np.ndarray]:
    """``mu (n, n)`` and ``nu (n,)`` of ``T = 1/2 sum_ij mu_ij w_i' . w_j'``, ``Pi = g sum_i nu_i w_i . up``
    straight from the point masses, not from :mod:`exo_bench.models.mechanism.aggregates`: mass ``m`` of link ``k`` at
    fraction ``f`` sits at ``sum_{a in anc(k)} w_a + f w_k``, so it adds ``m c_i c_j`` to ``mu_ij``
    and ``m c_i`` to ``nu_i`` with ``c_a = 1`` on the ancestors and ``c_k = f``."""
    n = len(mech.parent)
    mu, nu = np.zeros((n, n)), np.zeros(n)
    for k in range(n):
        anc, p = [], mech.parent[k]
        while p >= 0:
            anc.append(p)
            p = mech.parent[p]
        for m, f in zip(mech.masses[k], (0.0, mech.n[k], 1.0)):
            c = np.zeros(n)
            c[anc] = 1.0
            c[k] = f
            mu += m * np.outer(c, c)
            nu += m * c
    return mu, nu


#: Metres of lever arm that Pinocchio's moments carry in rounding whatever the rods' lengths: it
#: composes placements and rotations, so the moment of a point mass about a joint at (exactly) the
#: same place is not exactly zero. Hypothesis found moments of ``m |a| * 6e-19 m`` there (m the
#: mass, |a| its acceleration with g) and ``0.33 eps m v^2`` (the spatial cross product of the
#: velocity, v the point's speed); ``K eps 0.05 m * m |a|`` bounds the first with a margin of 10
#: and loosens the rows of 1 m rods by a few percent.
LEVER_ROUNDING = 0.05
#: Likewise the moment ``m v^2`` of the spatial cross products at zero lever arm: measured
#: ``0.33 eps m v^2``; ``K eps / 8 * m v^2`` (v bounded by the rates along the path to the root)
#: leaves a factor of 3.
SPEED_ROUNDING = 1 / 8


def _lever_arms(mech, q) -> np.ndarray:
    """``|r_a|`` of every coordinate ``a``, ``(S, dof)``: ``l_i`` for an angle, 1 for a length."""
    n = mech.nlinks
    l = q[:, -n:]
    return np.concatenate([l] * (mech.dim - 1) + [np.ones_like(l)], axis=1)


def _link_of_row(mech) -> np.ndarray:
    return np.tile(np.arange(mech.nlinks), mech.dim)


def _subtree_rows(mech) -> np.ndarray:
    """``(dof, dof)``: row ``a`` of an angle of link ``i`` sums the rows of the same angle of i's
    subtree; identity on the lengths. An angle's force is a joint moment minus those of the child
    joints in Pinocchio (``tau = G^T tau_joint``), and a joint's moment sums its subtree: its
    rounding is that of the subtree's terms."""
    n = mech.nlinks
    sub = np.eye(n)
    for k in range(n):
        p = mech.parent[k]
        while p >= 0:
            sub[p, k] = 1.0
            p = mech.parent[p]
    R = np.eye(mech.dof)
    for b in range(mech.dim - 1):
        R[b * n : (b + 1) * n, b * n : (b + 1) * n] = sub
    return R


def _rates(mech, q, qd, qdd):
    """``q`` as a 2D float array, the lengths, ``|phi'|``, ``|psi'|`` (zeros in 2D), ``|l'|`` per link
    (each ``(S, n)``), and ``kappa``, the bound on ``|d2/dt2 (l u)|`` of every rod (:func:`term_scale`)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = mech.nlinks
    qd = np.zeros_like(q) if qd is None else np.atleast_2d(np.asarray(qd, dtype=float))
    qdd = np.zeros_like(q) if qdd is None else np.atleast_2d(np.asarray(qdd, dtype=float))
    l = q[:, -n:]
    ad, add = np.abs(qd), np.abs(qdd)
    wd, ld = ad[:, :n], ad[:, -n:]
    vd = ad[:, n : 2 * n] if mech.dim == 3 else np.zeros_like(wd)
    wdd, ldd = add[:, :n], add[:, -n:]
    vdd = add[:, n : 2 * n] if mech.dim == 3 else np.zeros_like(wdd)
    kappa = l * (wdd + vdd + wd**2 + vd**2 + 2 * wd * vd) + ldd + 2 * ld * (wd + vd)
    return q, l, wd, vd, ld, kappa


def term_scale(mech, q, qd=None, qdd=None, gravity: bool = True) -> np.ndarray:
    """Per sample and row, a bound on the sum of the magnitudes of the terms of ``tau(q, qd, qdd)``
    (times ``max(1, |angles|)``, the rounding of large angles), ``(S, dof)``.

    Row ``a`` of link ``i`` is ``r_a . (sum_j mu_ij s_i s_j kappa_j + g nu_i s_i up)`` (the
    derivation in :mod:`exo_bench.matrix_method.closed_forms.planar`) with ``kappa_j = d2/dt2(l_j u_j)``, whose eight terms
    are bounded by ``l (|phi''| + |psi''| + phi'^2 + psi'^2 + 2 |phi' psi'|) + |l''| + 2 |l'| (|phi'| + |psi'|)``
    (every derivative of ``u`` has norm at most 1). ``mu, nu`` come from
    :func:`mass_coupling_oracle`, so no implementation under test sets its own tolerance."""
    q, l, wd, vd, ld, kappa = _rates(mech, q, qd, qdd)
    n = mech.nlinks
    mu, nu = mass_coupling_oracle(mech)
    per_link = kappa @ np.abs(mu).T + (mech.g * np.abs(nu) if gravity else 0.0)  # (S, n)
    angles = np.maximum(1.0, np.abs(q[:, :-n]).max(axis=1, initial=0.0))[:, None]
    rows = _lever_arms(mech, q) * per_link[:, _link_of_row(mech)] * angles
    # every point mass's own moment about its link's joint, with the lever arm of the rounding,
    # and its spatial cross products v x (m v) (a moment m v^2 even at zero lever arm)
    link_speed = ld + l * (wd + vd)
    path_speed = np.stack([link_speed[:, [i, *mech.ancestors[i]]].sum(axis=1) for i in range(n)], axis=1)
    own = np.array([sum(mech.masses[i]) for i in range(n)])[None, :] * (
        LEVER_ROUNDING * (kappa.max(axis=1, initial=0.0)[:, None] + (mech.g if gravity else 0.0))
        + SPEED_ROUNDING * path_speed**2
    )
    rows[:, : (mech.dim - 1) * n] += np.tile(own, mech.dim - 1) * angles
    return rows @ _subtree_rows(mech).T


def mass_matrix_scale(mech, q, derived: bool = False) -> np.ndarray:
    """``|r_a| |mu_ij| |r_b|`` for entry ``(a, b)`` of ``M`` (links ``i, j``), ``(S, dof, dof)``:
    the magnitude of the one term of each entry, times ``max(1, |angles|)``.

    ``derived``: ``M`` obtained from inverse dynamics as ``ID(q, 0, e_b) - ID(q, 0, 0)``
    (:func:`exo_bench.models.runtime.prepared.terms_from_inverse_dynamics`), whose column ``b`` also carries the
    rounding of the gravity forces it subtracts: the term scale of ``ID(q, 0, e_b)`` is added."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    mu, _ = mass_coupling_oracle(mech)
    r = _lever_arms(mech, q)
    link = _link_of_row(mech)
    angles = np.maximum(1.0, np.abs(q[:, : -mech.nlinks]).max(axis=1, initial=0.0))[:, None, None]
    R = _subtree_rows(mech)
    out = R @ (r[:, :, None] * np.abs(mu)[link][:, link][None] * r[:, None, :]) @ R.T * angles
    if derived:
        for b in range(mech.dof):
            e = np.zeros_like(q)
            e[:, b] = 1.0
            out[:, :, b] += term_scale(mech, q, None, e)
    return out


def matrix_scale(mech, q) -> np.ndarray:
    """Per sample, a bound on the magnitude of element ``(i, j)`` of any matrix of eq. (5)/(17) and
    on what reading it off another implementation can add, ``(S, n, n)``: ``|mu_ij|`` times at most
    two lengths, plus the gravity term ``g |nu_i| max(1, l_i)`` (Pinocchio's matrices are differences
    of bias forces that contain it), summed over i's subtree (joint moments, see
    :func:`_subtree_rows`), times ``max(1, |angles|)``. The gravity vector ``P`` uses the diagonal."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = mech.nlinks
    mu, nu = mass_coupling_oracle(mech)
    L = np.maximum(1.0, q[:, -n:])
    per = L[:, :, None] * np.abs(mu)[None] * L[:, None, :] + (mech.g * np.abs(nu) * L)[:, :, None]
    sub = _subtree_rows(mech)[:n, :n] if mech.dim > 1 else np.eye(n)
    angles = np.maximum(1.0, np.abs(q[:, :-n]).max(axis=1, initial=0.0))[:, None, None]
    return sub @ per * angles


#: MuJoCo's com-based frame. MuJoCo's RNE and CRB (mj_comPos, mj_comVel, mj_rne, mj_makeM) express
#: every spatial quantity at one point per kinematic tree, the tree's centre of mass ``c``
#: (``subtree_com`` of its root body), not at the joint: a joint's degree of freedom is
#: ``cdof = [w; w x (c - p)]``, a body's inertia is ``m [|p - c|^2, |p - c|, 1]`` about ``c``, and a
#: moment about a joint is a moment about ``c`` plus ``(c - p) x f``. Each such product is rounded at
#: its own magnitude before the terms cancel back to the moment about the joint: a term of
#: ``m |a| D`` (forces of an angle), ``m |a|`` (of a length), and ``m D^2, m D, m`` (mass-matrix
#: entries of two angles, an angle and a length, two lengths), where ``D`` bounds ``|p - c|`` and
#: ``|c - p_joint|``. ``c`` is a mass-weighted mean of points of the tree, so ``D`` is at most the
#: sum ``L_T`` of the rod lengths of the tree (any two points of a tree are joined along its rods);
#: ``m`` is at most the tree's mass ``M_T``. ``|a|`` is a point's acceleration with gravity, at most
#: the largest path sum of :func:`term_scale`'s ``kappa`` plus ``g``, plus the velocity products of
#: the com-based frame, ``W_T (V_T + W_T L_T)``: ``W_T`` bounds every body's angular speed (each
#: MuJoCo hinge turns at ``phi_k' - phi_p'``, ``-psi_p'`` or ``psi_k'``, so ``2 sum (|phi'| + |psi'|)``
#: over the tree) and ``V_T`` every point's speed. Pinocchio and Drake work at the joints (local
#: frames, body origins): this term is MuJoCo's alone (``com_frame=True``).
def com_frame_scale(mech, q, qd=None, qdd=None, gravity: bool = True, matrix: bool = False) -> np.ndarray:
    """MuJoCo's com-based rounding (see above): ``(S, dof)`` for forces, ``(S, dof, dof)`` with
    ``matrix=True`` for the mass matrix; mapped to the paper's rows like :func:`term_scale`."""
    q, l, wd, vd, ld, kappa = _rates(mech, q, qd, qdd)
    n, S = mech.nlinks, q.shape[0]
    root = np.array([([i, *mech.ancestors[i]])[-1] for i in range(n)])
    trees = [np.flatnonzero(root == r) for r in np.unique(root)]
    path_kappa = np.stack([kappa[:, [i, *mech.ancestors[i]]].sum(axis=1) for i in range(n)], axis=1)
    angle = np.tile(np.arange(mech.dof) < (mech.dim - 1) * n, 1)  # rows of angles
    link = _link_of_row(mech)
    out = np.zeros((S, mech.dof, mech.dof) if matrix else (S, mech.dof))
    for t in trees:
        M_T = sum(sum(mech.masses[i]) for i in t)
        L_T = l[:, t].sum(axis=1)
        W_T = 2 * (wd[:, t] + vd[:, t]).sum(axis=1)
        V_T = (ld[:, t] + l[:, t] * W_T[:, None]).sum(axis=1)
        rows = np.isin(link, t)
        lever = np.where(angle[None, :], L_T[:, None], 1.0) * rows[None, :]  # (S, dof)
        if matrix:
            out += M_T * lever[:, :, None] * lever[:, None, :]
        else:
            A_T = path_kappa[:, t].max(axis=1) + (mech.g if gravity else 0.0) + W_T * (V_T + W_T * L_T)
            out += M_T * A_T[:, None] * lever
    angles = np.maximum(1.0, np.abs(q[:, :-n]).max(axis=1, initial=0.0))
    R = _subtree_rows(mech)
    if matrix:
        return R @ out @ R.T * angles[:, None, None]
    return out @ R.T * angles[:, None]


def assert_matrices_agree(ours: dict, ref: dict, mech, q, k: float = K, blocks=None) -> float:
    """Every matrix of ``ref`` (``block -> name -> (S, n, n)``, ``P``: ``(S, n)``) equals ours within
    ``k eps`` :func:`matrix_scale`; returns the largest ratio."""
    scale = matrix_scale(mech, q)
    worst = 0.0
    for block in blocks or ref:
        for name, x in ref[block].items():
            sc = np.diagonal(scale, axis1=1, axis2=2) if name == "P" else scale
            worst = max(worst, assert_close(ours[block][name], x, sc, k, what=f"{block}.{name}"))
    return worst


def assert_close(a, b, scale, k: float = K, what: str = "") -> float:
    """Assert ``|a - b| <= k * eps * scale`` elementwise (``scale`` broadcasts against ``a``); return
    the largest ratio ``|a - b| / (eps * scale)``, the measured disagreement in ulps of the scale."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, (a.shape, b.shape, what)
    assert np.isfinite(a).all() and np.isfinite(b).all(), what
    scale = np.broadcast_to(scale, a.shape)
    diff = np.abs(a - b)
    with np.errstate(divide="ignore", invalid="ignore"):  # a zero scale allows no difference at all
        ratio = float(np.where(diff == 0, 0.0, diff / (EPS * scale)).max())
    assert ratio <= k, f"{what}: disagreement {ratio:.3g} eps * scale > {k} (max |a - b| = {diff.max():.3g})"
    return ratio


def assert_forces_agree(a, b, mech, q, qd, qdd, k: float = K, what: str = "", com_frame: bool = False) -> float:
    """:func:`assert_close` of two ``tau(q, qd, qdd)``, ``(S, dof)``, with :func:`term_scale` (plus
    :func:`com_frame_scale` with ``com_frame=True``: one side is MuJoCo)."""
    scale = term_scale(mech, q, qd, qdd)
    if com_frame:
        scale = scale + com_frame_scale(mech, q, qd, qdd)
    return assert_close(a, b, scale, k, what)


def assert_mass_matrices_agree(a, b, mech, q, k: float = K, what: str = "", com_frame: bool = False) -> float:
    """:func:`assert_close` of two ``M(q)``, ``(S, dof, dof)``, with :func:`mass_matrix_scale` (plus
    :func:`com_frame_scale` with ``com_frame=True``: one side is MuJoCo)."""
    scale = mass_matrix_scale(mech, q)
    if com_frame:
        scale = scale + com_frame_scale(mech, q, matrix=True)
    return assert_close(a, b, scale, k, what)


def rel_err(a, b) -> float:
    """Largest absolute difference relative to the largest magnitude of the reference."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


@pytest.fixture
def rel():
    return rel_err


def uniform_states(mech, samples: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seeded ``q, qd, qdd``, ``(samples, dof)``, away from any motion: angles uniform on the whole circle,
    rod lengths uniform in [0.2, 1.2], rates standard normal (the states of the compiled kernels' tests,
    whose error model assumes angles and rates O(1) and lengths in [0.2, 1.2])."""
    rng = np.random.default_rng(seed)
    n = mech.nlinks
    q = rng.uniform(-np.pi, np.pi, (samples, mech.dof))
    q[:, -n:] = rng.uniform(0.2, 1.2, (samples, n))
    return q, rng.normal(size=q.shape), rng.normal(size=q.shape)


def smooth_states(mech, samples: int, seed: int) -> list[np.ndarray]:
    """``q, qd, qdd`` (C-ordered, ``(samples, dof)``) of a seeded smooth motion of ``mech`` over 2 s
    (:func:`exo_bench.models.gait.motion.smooth_random_motion`)."""
    from exo_bench.models.gait.motion import smooth_random_motion

    mo = smooth_random_motion(mech, np.linspace(0.0, 2.0, samples), seed=seed)
    return [np.ascontiguousarray(a) for a in (mo.q, mo.qd, mo.qdd)]


#: Power balance against the sixth-order difference of the energy (``h = 1e-3``): truncation
#: ``O(h^6) = 1e-18`` times the seventh derivative of the energy (smooth motions of a few
#: harmonics), plus the rounding of the stencil, ``eps * |T + Pi| / h ~ 2e-13 |T + Pi|``, relative
#: to the largest rate. Measured at most 8e-13 on every seeded tree of the tests; 1e-11 leaves the
#: stencil's rounding a factor of 10 and catches a formula error of 1e-10 relative in tau.
POWER_BALANCE_TOL = 1e-11


def power_balance_residual(inverse_dynamics, mech, seed: int) -> float:
    """max |tau . qd - d(T+Pi)/dt| / max |d(T+Pi)/dt| along a seeded smooth motion, with T and Pi
    summed over the point masses (models.kinematics): the power balance every method must satisfy."""
    from exo_bench.models.mechanism.kinematics import energy_rate
    from exo_bench.models.gait.motion import smooth_random_motion

    f = lambda t: smooth_random_motion(mech, t, seed=seed)
    t = np.linspace(0.0, 3.0, 40)
    mo = f(t)
    power = (inverse_dynamics(mech, mo.q, mo.qd, mo.qdd) * mo.qd).sum(1)
    rate = energy_rate(mech, f, t)
    return float(np.abs(power - rate).max() / np.abs(rate).max())


def run_in_threads(work, count: int) -> None:
    """``work(k)`` for ``k = 0 .. count - 1``, each in its own thread, all started before any is joined."""
    import threading

    threads = [threading.Thread(target=work, args=(k,)) for k in range(count)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()


_INSTALLED: list[str] | None = None


def installed_methods() -> list[str]:
    """Every registered method whose engine is installed here, in registry order.

    ``mujoco`` and ``drake`` are the optional extra ``[peers]``: where it is missing, preparing them
    raises :class:`~exo_bench.models.runtime.prepared.MissingExtra`, and the tests that iterate over every
    method leave them out (tests/test_mujoco_drake.py skips with the reason printed). Found by
    preparing each method once on the one-link planar model, so a method that is merely slow to
    import is not mistaken for a missing one."""
    global _INSTALLED
    if _INSTALLED is None:
        from exo_bench import method_names, prepare
        from exo_bench.models.runtime.prepared import MissingExtra
        from exo_bench.models.mechanism.presets import fig1

        found = []
        for name in method_names():
            try:
                prepare(fig1(2), name)
            except MissingExtra:
                continue
            found.append(name)
        _INSTALLED = found
    return list(_INSTALLED)


@pytest.fixture(scope="session")
def warm_package(tmp_path_factory):
    """A copy of the package whose numba cache holds the kernels of the stale-cache probes, compiled once
    per session (tests/package_copy.py): the template a test copies whole when it is not about a cold
    compile. Never edited; each test edits its own copy."""
    from package_copy import warm_package

    return warm_package(tmp_path_factory.mktemp("warm-package"))


def pytest_collection_modifyitems(items):
    """No hypothesis test depends on the machine's speed (issue 34, F1): every one runs without a
    deadline and with the ``too_slow`` health check off, whatever its own settings say (both time
    the examples on the wall clock; a loaded machine failed them). Set here, as hypothesis's own
    pytest plugin sets its per-item settings, so that a new test cannot forget it. Nor does one depend
    on the run: every run draws the same examples (``derandomize``: a seed from the test's name; no
    example database replaying another run's finds), so the README's test command is repeatable."""
    from hypothesis import HealthCheck, settings

    for item in items:
        fn = getattr(getattr(item, "obj", None), "__func__", getattr(item, "obj", None))
        if getattr(fn, "is_hypothesis_test", False):
            own = fn._hypothesis_internal_use_settings
            fn._hypothesis_internal_use_settings = settings(
                parent=own,
                deadline=None,
                derandomize=True,
                database=None,
                suppress_health_check={HealthCheck.too_slow} | set(own.suppress_health_check),
            )
