"""Analytic derivatives of inverse dynamics (models/newton_euler/derivatives.py and its kernels).

Oracles: CasADi's algorithmic differentiation of the factored closed forms (today's
``model.derivatives``), to 1e-13 relative; complex-step derivatives of the numpy passes
(:func:`exo_bench.models.newton_euler.passes.inverse_dynamics` on complex states) and of the rod elements,
to the error model of :func:`derivative_scales`; ``M`` against the prepared model's mass matrix to the
conftest error model.

**Error model of the complex step.** ``Im f(x + i h) / h`` with ``h = 1e-30`` has a truncation error of
``O(h^2 f''')``, below 1e-50 relative here, and no subtraction: its rounding is that of evaluating
``f``'s derivative terms, as the analytic side's is. Each entry is a sum of products of at most ~8
rounded factors, so both differ by at most ``K eps`` (conftest's ``K``) times the sum of the magnitudes
of the terms of the entry, bounded from the mechanism and the states alone (no code under test): for
``dtau_a/dq_b`` (rows ``a`` of link ``i``, columns ``b`` of link ``j``) ``|r_a| |mu_ij| A_j + delta_ij
(|r_a| + 1) F_i``, for ``dtau_a/dqd_b`` ``|r_a| |mu_ij| R_j``, with ``|r_a|`` the lever arm (``l_i`` for an
angle, 1 for a length), ``A_j = kappa_j (1 + 1/l_j)`` (``kappa_j`` conftest's bound on ``|(l u)''|``; every
derivative of ``u`` has norm at most 1, and ``d/dl`` divides the terms by ``l``), ``R_j = 2 (l_j + 1) (|phi_j'| +
|psi_j'|) + 2 |l_j'|`` and ``F_i = sum_j |mu_ij| kappa_j + g |nu_i|``, all times ``max(1, |angles|)``.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from conftest import EPS, K, _rates, assert_close, assert_mass_matrices_agree, mass_coupling_oracle, mass_matrix_scale

import exo_bench
from exo_bench.matrix_method.derivatives import derivatives_of as casadi_derivatives_of
from exo_bench.models.mechanism import presets
from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.mechanism import rod_elements as el
from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.derivatives import prepare_inverse_derivatives
from exo_bench.models.newton_euler.passes import prepare_tree

H = 1e-30  # the complex step
CASADI_RTOL = 1e-13  # the criterion: relative to the largest entry of the sample's matrix


@functools.cache
def casadi_derivatives(mech):
    """CasADi's algorithmic differentiation of the factored closed forms (model.derivatives before
    issue 36; ``model.derivatives`` now runs the kernels under test)."""
    d = casadi_derivatives_of(mech, "matrix-factored")
    assert "CasADi" in d.source, d.source
    return d


def states(mech, samples: int, seed: int):
    """Seeded states: angles in [-1.5, 1.5] (elevations within +-1.2 rad: no vertical rod), lengths in
    [0.3, 1.5], rates and accelerations N(0, 1)."""
    rng = np.random.default_rng(seed)
    n = mech.nlinks
    q = rng.uniform(-1.5, 1.5, (samples, mech.dof))
    if mech.dim == 3:
        q[:, n : 2 * n] = rng.uniform(-1.2, 1.2, (samples, n))
    q[:, -n:] = rng.uniform(0.3, 1.5, (samples, n))
    return q, rng.normal(size=q.shape), rng.normal(size=q.shape)


def derivative_scales(mech, q, qd, qdd):
    """``(scale_q, scale_qd)``, ``(S, dof, dof)``: the module docstring's error model."""
    q, l, wd, vd, ld, kappa = _rates(mech, q, qd, qdd)
    n = mech.nlinks
    mu, nu = mass_coupling_oracle(mech)
    link = np.tile(np.arange(n), mech.dim)
    lever = np.concatenate([l] * (mech.dim - 1) + [np.ones_like(l)], axis=1)  # (S, dof)
    acc = np.where(l > 0, kappa * (1 + 1 / np.where(l > 0, l, 1.0)), np.inf)  # vacuous at l = 0
    rate = 2 * (l + 1) * (wd + vd) + 2 * ld
    force = kappa @ np.abs(mu).T + mech.g * np.abs(nu)  # (S, n)
    angles = np.maximum(1.0, np.abs(q[:, :-n]).max(axis=1))[:, None, None]
    M = np.abs(mu)[link][:, link][None]
    same = (link[:, None] == link[None, :])[None]
    sqd = lever[:, :, None] * M * rate[:, None, link]
    with np.errstate(invalid="ignore"):  # 0 * inf at l = 0: made inf, vacuous
        sq = lever[:, :, None] * M * acc[:, None, link] + same * ((lever + 1) * force[:, link])[:, :, None]
        return np.nan_to_num(sq * angles, nan=np.inf), sqd * angles


def complex_step(mech, q, qd, qdd):
    """``dtau/dq`` and ``dtau/dqd`` column by column from the numpy passes on complex states."""
    tree, dim, g = prepare_tree(mech), mech.dim, float(mech.g)
    S, dof = q.shape
    out = np.empty((2, S, dof, dof))
    for b in range(dof):
        step = np.zeros((S, dof), dtype=complex)
        step[:, b] = 1j * H
        out[0][:, :, b] = passes.inverse_dynamics(tree, dim, g, q + step, qd + 0j, qdd + 0j).imag / H
        out[1][:, :, b] = passes.inverse_dynamics(tree, dim, g, q + 0j, qd + step, qdd + 0j).imag / H
    return out


MECHS = [
    pytest.param(lambda: presets.random_tree(7, 2, 3), id="tree7-2d"),
    pytest.param(lambda: presets.random_tree(7, 3, 3), id="tree7-3d"),
    pytest.param(lambda: presets.random_tree(9, 3, 11), id="tree9-3d"),
    pytest.param(lambda: presets.chain(5, 2, seed=2), id="chain5-2d"),
    pytest.param(lambda: presets.exo5(3), id="exo5-3d"),
]
KERNELS = ["numpy", "numba", "simd"]


@pytest.mark.parametrize("make", MECHS)
@pytest.mark.parametrize("kernel", KERNELS)
def test_agrees_with_casadi(make, kernel):
    """The issue's criterion: CasADi's derivatives (not model.derivatives, which runs these kernels now) to 1e-13 relative, trees with branch signs, 2D and 3D."""
    mech = make()
    q, qd, qdd = states(mech, 3, seed=5)
    ref = casadi_derivatives(mech).inverse_dynamics(q, qd, qdd)
    got = prepare_inverse_derivatives(mech)(q, qd, qdd, kernel=kernel)
    for name, a, b in zip(("dtau_dq", "dtau_dqd", "M"), got, ref):
        for s in range(q.shape[0]):
            err = np.abs(a[s] - b[s]).max() / np.abs(b[s]).max()
            assert err <= CASADI_RTOL, f"{mech.name} {name} sample {s}: {err:.3g}"


def test_agrees_with_casadi_on_a_tree_of_100_links():
    """The large case the issue asks (n = 100), one sample, 2D: CasADi's 3D graph of 100 links takes
    tens of seconds to build and compile here (2D: about 3 s); 3D to n = 30 is covered by ``test_kernels_agree_to_rounding``
    and the benchmark's 50-digit reference."""
    mech = presets.random_tree(100, 2, 5)
    q, qd, qdd = states(mech, 1, seed=3)
    ref = casadi_derivatives(mech).inverse_dynamics(q, qd, qdd)
    for name, a, b in zip(("dtau_dq", "dtau_dqd", "M"), prepare_inverse_derivatives(mech)(q, qd, qdd), ref):
        err = np.abs(a - b).max() / np.abs(b).max()
        assert err <= CASADI_RTOL, f"{name}: {err:.3g}"


@pytest.mark.parametrize("make", MECHS)
def test_complex_step_of_the_passes(make):
    """The independent oracle: complex-step derivatives of the numpy passes, to the error model."""
    mech = make()
    q, qd, qdd = states(mech, 4, seed=8)
    dq, dqd, _ = prepare_inverse_derivatives(mech)(q, qd, qdd, kernel="numpy")
    cq, cqd = complex_step(mech, q, qd, qdd)
    sq, sqd = derivative_scales(mech, q, qd, qdd)
    assert_close(dq, cq, sq, K, what=f"{mech.name} dtau_dq")
    assert_close(dqd, cqd, sqd, K, what=f"{mech.name} dtau_dqd")


def test_complex_step_error_model_is_tight_enough():
    """The error model can fail: a change of 1e-12 relative in one entry of dtau/dq is far beyond it."""
    mech = presets.random_tree(7, 3, 3)
    q, qd, qdd = states(mech, 2, seed=8)
    dq, _, _ = prepare_inverse_derivatives(mech)(q, qd, qdd, kernel="numpy")
    cq, _ = complex_step(mech, q, qd, qdd)
    sq, _ = derivative_scales(mech, q, qd, qdd)
    bad = dq.copy()
    a, b = np.unravel_index(np.abs(dq[0]).argmax(), dq[0].shape)
    bad[0, a, b] *= 1 + 1e-12
    with pytest.raises(AssertionError):
        assert_close(bad, cq, sq, K)


@pytest.mark.parametrize("make", MECHS)
def test_mass_matrix_equals_the_prepared_models(make):
    """``M = dtau/dqdd`` equals newton-euler's mass matrix to the conftest error model."""
    mech = make()
    q, qd, qdd = states(mech, 3, seed=9)
    _, _, M = prepare_inverse_derivatives(mech)(q, qd, qdd, kernel="numpy")
    ref = exo_bench.prepare(mech, "newton-euler").mass_matrix(q)
    assert_mass_matrices_agree(M, ref, mech, q, what=mech.name)


def _complex_columns(f, args, which, h=H):
    """Complex-step derivatives of the element ``f`` (a tuple of outputs) in its arguments ``which``,
    as one flat column-major tuple (the layout of :mod:`.derivative_elements`)."""
    cols = []
    for i in which:
        z = [complex(a) for a in args]
        z[i] += 1j * h
        cols.extend(complex(x).imag / h for x in f(*z))
    return cols


def _angle_columns(f, args, angles, h=H):
    """As :func:`_complex_columns` for arguments given as ``(cos, sin)`` pairs at ``angles`` (their
    positions in ``args``, each the index of the cosine)."""
    cols = []
    for i in angles:
        z = [complex(a) for a in args]
        x = np.arctan2(args[i + 1], args[i]) + 1j * h
        z[i], z[i + 1] = np.cos(x), np.sin(x)
        cols.extend(complex(v).imag / h for v in f(*z))
    return cols


@pytest.mark.parametrize("seed", range(3))
def test_element_derivatives_are_complex_step_derivatives_of_the_elements(seed):
    """Each derivative element equals the complex step of the element it differentiates: an absolute
    tolerance of ``K eps`` times the sum of the magnitudes of its arguments' products (all O(1) here)."""
    rng = np.random.default_rng(seed)
    phi, psi = rng.uniform(-3, 3, 2)
    cf, sf, cp, sp = np.cos(phi), np.sin(phi), np.cos(psi), np.sin(psi)
    l, w, v, ld, wdd, vdd, ldd = rng.uniform(0.3, 1.5), *rng.normal(size=6)
    fx, fy, fz = rng.normal(size=3)
    tol = K * EPS * 50
    acc2 = lambda c, s, L, W, LD, WDD, LDD: el.rod_acceleration_2d(c, s, L, W, LD, WDD, LDD)  # noqa: E731
    pairs = [
        (de.jacobian_2d(cf, sf, l), _complex_columns(acc2, (cf, sf, l, w, ld, wdd, ldd), (5, 6))),
        (
            de.acceleration_by_q_2d(cf, sf, l, w, ld, wdd, ldd),
            _angle_columns(acc2, (cf, sf, l, w, ld, wdd, ldd), (0,))
            + _complex_columns(acc2, (cf, sf, l, w, ld, wdd, ldd), (2,)),
        ),
        (de.acceleration_by_rates_2d(cf, sf, l, w, ld), _complex_columns(acc2, (cf, sf, l, w, ld, wdd, ldd), (3, 4))),
        (
            de.projection_by_q_2d(cf, sf, l, fx, fy),
            _angle_columns(el.project_2d, (cf, sf, l, fx, fy), (0,))
            + _complex_columns(el.project_2d, (cf, sf, l, fx, fy), (2,)),
        ),
    ]
    args3 = (cf, sf, cp, sp, l, w, v, ld, wdd, vdd, ldd)
    pargs3 = (cf, sf, cp, sp, l, fx, fy, fz)
    pairs += [
        (de.jacobian_3d(cf, sf, cp, sp, l), _complex_columns(el.rod_acceleration_3d, args3, (8, 9, 10))),
        (
            de.acceleration_by_q_3d(*args3),
            _angle_columns(el.rod_acceleration_3d, args3, (0, 2))
            + _complex_columns(el.rod_acceleration_3d, args3, (4,)),
        ),
        (de.acceleration_by_rates_3d(*args3[:8]), _complex_columns(el.rod_acceleration_3d, args3, (5, 6, 7))),
        (
            de.projection_by_q_3d(*pargs3),
            _angle_columns(el.project_3d, pargs3, (0, 2)) + _complex_columns(el.project_3d, pargs3, (4,)),
        ),
    ]
    for got, want in pairs:
        np.testing.assert_allclose(np.asarray(got, dtype=float), want, rtol=0, atol=tol)


@pytest.fixture(scope="module")
def exo5_derivatives():
    return prepare_inverse_derivatives(presets.exo5(3))


def _good(d, samples=2):
    return states(d.mechanism, samples, seed=1)


@pytest.mark.parametrize(
    "field, make, expected",
    [
        ("q", lambda q: q.tolist(), "expected a numpy.ndarray of float64, got list"),
        ("qd", lambda q: q.astype(np.float32), "expected dtype float64, got float32"),
        ("qdd", lambda q: q[:, :-1].copy(), "expected shape (15,) or (samples, 15), got (2, 14)"),
        ("q", lambda q: np.asfortranarray(np.vstack([q, q])), "expected a C-contiguous array"),
        ("qd", lambda q: q[:1].copy(), "expected shape (2, 15) (as q), got (1, 15)"),
    ],
)
def test_bad_states_are_named(exo5_derivatives, field, make, expected):
    """Bad shapes, dtypes and layouts: a ValueError naming the field, the expected and the actual value."""
    q, qd, qdd = _good(exo5_derivatives)
    args = {"q": q, "qd": qd, "qdd": qdd}
    args[field] = make(args[field])
    if field == "q" and "C-contiguous" in expected:
        args["qd"], args["qdd"] = np.vstack([qd, qd]), np.vstack([qdd, qdd])
    with pytest.raises(ValueError, match=f"field '{field}'") as e:
        exo5_derivatives(args["q"], args["qd"], args["qdd"])
    assert expected in str(e.value)


def test_aliasing_or_bad_out_is_named(exo5_derivatives):
    """``out``: overlapping an input or another output, read-only, strided or misshapen: named, nothing written."""
    d = exo5_derivatives
    q, qd, qdd = _good(d)
    outs = [np.zeros((2, 15, 15)) for _ in range(3)]
    with pytest.raises(ValueError, match=r"field 'out\[1\]' \(dtau_dqd\): expected memory apart from out\[0\]"):
        d(q, qd, qdd, out=(outs[0], outs[0], outs[2]))
    big = np.zeros(2 * 15 * 15 + 30)
    qv = big[:30].reshape(2, 15)
    qv[...] = q
    with pytest.raises(ValueError, match=r"field 'out\[0\]' \(dtau_dq\): expected memory apart from q"):
        d(qv, qd, qdd, out=(big[: 2 * 225].reshape(2, 15, 15), outs[1], outs[2]))
    ro = np.zeros((2, 15, 15))
    ro.flags.writeable = False
    with pytest.raises(
        ValueError, match=r"field 'out\[2\]' \(M\): expected a writable C-contiguous array, got read-only"
    ):
        d(q, qd, qdd, out=(outs[0], outs[1], ro))
    with pytest.raises(
        ValueError, match=r"field 'out\[0\]' \(dtau_dq\): expected shape \(2, 15, 15\), got \(2, 15, 14\)"
    ):
        d(q, qd, qdd, out=(np.zeros((2, 15, 14)), outs[1], outs[2]))
    with pytest.raises(ValueError, match=r"field 'out': expected a tuple of 3 arrays"):
        d(q, qd, qdd, out=outs[0])
    with pytest.raises(ValueError, match=r"option 'kernel': expected one of"):
        d(q, qd, qdd, kernel="fortran")
    assert not any(o.any() for o in outs)


def test_out_is_filled_and_returned_and_one_sample_is_a_matrix(exo5_derivatives):
    """``out`` receives the result (and is returned); one ``(dof,)`` sample gives ``(dof, dof)``
    matrices equal to that sample's rows of a batch."""
    d = exo5_derivatives
    q, qd, qdd = _good(d)
    outs = tuple(np.full((2, 15, 15), np.nan) for _ in range(3))
    got = d(q, qd, qdd, out=outs, kernel="numpy")
    assert all(g is o for g, o in zip(got, outs))
    one = d(q[1], qd[1], qdd[1], kernel="numpy")
    for a, b in zip(one, outs):
        assert a.shape == (15, 15)
        np.testing.assert_array_equal(a, b[1])
    empty = d(q[:0], qd[:0], qdd[:0])
    assert all(e.shape == (0, 15, 15) for e in empty)


@pytest.mark.parametrize("make", MECHS[:4])
def test_kernels_agree_to_rounding(make):
    """numpy, numba (per sample, and its parallel driver) and simd compute the same terms; their sin/cos
    differ by an ulp or two and the sums run in other orders: the complex step's error model bounds it."""
    from exo_bench.models.newton_euler import derivatives_compiled as dc

    mech = make()
    d = prepare_inverse_derivatives(mech)
    q, qd, qdd = states(mech, 37, seed=4)  # one whole SIMD block and a partial one
    ref = d(q, qd, qdd, kernel="numpy")
    sq, sqd = derivative_scales(mech, q, qd, qdd)
    scales = (sq, sqd, mass_matrix_scale(mech, q))
    par = tuple(np.empty_like(r) for r in ref)
    dc.derivatives_parallel(d.table, d.mu, d.g, d.dim, q, qd, qdd, *par)
    for kernel, got in (
        ("numba", d(q, qd, qdd, kernel="numba")),
        ("simd", d(q, qd, qdd, kernel="simd")),
        ("parallel", par),
    ):
        for name, a, b, sc in zip(("dtau_dq", "dtau_dqd", "M"), got, ref, scales):
            assert_close(a, b, sc, K, what=f"{mech.name} {kernel} {name}")
    one = d(q[3], qd[3], qdd[3])  # the lean one-sample entry
    serial = d(q, qd, qdd, kernel="numba")
    for a, b in zip(one, serial):
        np.testing.assert_array_equal(a, b[3])


def test_one_sample_overlap_is_found_by_the_kernel(exo5_derivatives):
    """The one-sample entry tests the overlap of ``out`` with the states inside the kernel: named, nothing written."""
    d = exo5_derivatives
    q, qd, qdd = (x[0].copy() for x in _good(d))
    buf = np.zeros(15 * 15)
    qv = buf[:15]
    qv[...] = q
    outs = (buf.reshape(15, 15), np.zeros((15, 15)), np.zeros((15, 15)))
    with pytest.raises(ValueError, match=r"field 'out\[0\]' \(dtau_dq\): expected memory apart from q"):
        d(qv, qd, qdd, out=outs)
    np.testing.assert_array_equal(buf[15:], 0.0)
    with pytest.raises(ValueError, match=r"field 'out\[2\]' \(M\): expected memory apart from out\[1\]"):
        d(q, qd, qdd, out=(np.zeros((15, 15)), outs[1], outs[1]))
    with pytest.raises(ValueError, match=r"field 'qd': expected dtype float64, got float32"):
        d(q, qd.astype(np.float32), qdd)


def test_one_sample_path_names_a_bad_out_and_runs_an_unaligned_one(exo5_derivatives):
    """What the lean one-sample entry does not take goes to the checked path: a read-only or Fortran-ordered
    ``out`` is named; an unaligned (but otherwise good) ``out`` is computed, equal to the lean result."""
    d = exo5_derivatives
    q, qd, qdd = (x[0].copy() for x in _good(d))
    want = d(q, qd, qdd)
    ro = np.zeros((15, 15))
    ro.flags.writeable = False
    with pytest.raises(
        ValueError, match=r"field 'out\[1\]' \(dtau_dqd\): expected a writable C-contiguous array, got read-only"
    ):
        d(q, qd, qdd, out=(np.zeros((15, 15)), ro, np.zeros((15, 15))))
    with pytest.raises(
        ValueError, match=r"field 'out\[0\]' \(dtau_dq\): expected a writable C-contiguous array, got strides"
    ):
        d(q, qd, qdd, out=(np.zeros((15, 15), order="F"), np.zeros((15, 15)), np.zeros((15, 15))))
    raw = np.zeros(15 * 15 * 8 + 1, dtype=np.uint8)
    unaligned = raw[1:].view(np.float64).reshape(15, 15)
    assert not unaligned.flags.aligned
    got = d(q, qd, qdd, out=(unaligned, np.zeros((15, 15)), np.zeros((15, 15))))
    for a, b in zip(got, want):
        np.testing.assert_array_equal(a, b)
