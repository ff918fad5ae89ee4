"""Forward dynamics and its derivatives answer or refuse, never both wrong and silent (issue 34: W2, W3,
W4, T5).

**The one conditioning test** (:mod:`exo_bench.models.runtime.conditioning`) is shared by every method's
forward dynamics, by ``model.derivatives.forward_dynamics`` and by ``exo-bench forward``. Its bound
comes from the error model (tests/conftest.py): every method computes ``M`` to ``K eps`` of its term
scale, lever arms ``l_i`` on the angles' rows, so the rod lengths drop out, and the solve magnifies
that by ``kappa = cond(mu_s) max(1, |angles|) / min_i cos^2 psi_i``. An answer whose error bound
``K eps kappa`` exceeds ``FORWARD_RTOL`` is refused, naming the sample, the link and the reason.
Within the bound, every answer's backward error ``|M qdd + h - tau|`` (each method's own inverse
dynamics) stays within the error model's row scale.

Oracles independent of the code under test: ``cond(mu_s)`` is computed densely here from
conftest's :func:`mass_coupling_oracle`; the rows' scale is conftest's ``term_scale`` and
``mass_matrix_scale``.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from cli_runs import cli_process
from conftest import EPS, K, installed_methods, mass_coupling_oracle, mass_matrix_scale, term_scale
from hypothesis import given, settings
from hypothesis import strategies as st

from exo_bench import prepare
from exo_bench.api.methods import known_wrong_warning
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, random_tree
from exo_bench.models.mechanism.singularity import SingularConfigurationError

#: Lagrange derives its equations symbolically: only on small trees.
LAGRANGE_MAX_LINKS = 3


def _models(mech, methods=None):
    out = {}
    for name in methods or installed_methods():
        if name == "lagrange" and mech.nlinks > LAGRANGE_MAX_LINKS and mech.name != "exo5-3d":
            continue
        out[name] = prepare(mech, name)
    if "newton-euler" in out:
        out["newton-euler (numpy)"] = prepare(mech, "newton-euler", kernel="numpy")
    return out


def _state(mech, seed):
    q, qd, _ = random_states(mech, 1, seed)
    tau = np.random.default_rng(seed).uniform(-20, 20, q.shape)
    return q, qd, tau


def _mu_condition(mech) -> float:
    """``cond_1(D^-1/2 mu D^-1/2)``, ``D = diag(mu)``, dense, from conftest's point-mass oracle (what the
    package estimates in O(n))."""
    mu, _ = mass_coupling_oracle(mech)
    r = 1 / np.sqrt(np.diag(mu))
    return float(np.linalg.cond(mu * r[:, None] * r[None, :], 1))


# --------------------------------------------------------------------------- W2: tiny rods
@pytest.mark.case("W2")
@pytest.mark.parametrize("dim, link, length", [(3, 4, 1e-300), (2, 2, 1e-250), (3, 0, 3e-200), (2, 4, 1e-160)])
def test_a_rod_too_short_for_working_precision_is_refused_by_every_method_naming_link_and_field(dim, link, length):
    """A rod length below working precision (``l5 = 1e-300``) is refused by every method, naming the
    sample, the link and the field ``l5``, never inf or NaN. At ``l -> 0`` an angle's acceleration
    grows like ``1/l`` (its rows of ``M`` like ``l^2``): a pole, not a removable singularity."""
    mech = exo5(dim)
    n = mech.nlinks
    q, qd, tau = _state(mech, 11 + link)
    q = np.repeat(q, 3, axis=0)
    qd, tau = np.repeat(qd, 3, axis=0), np.repeat(tau, 3, axis=0)
    q[1, 2 * n + link if dim == 3 else n + link] = length
    for name, model in _models(mech).items():
        with pytest.raises(SingularConfigurationError) as e:
            model.forward_dynamics(q, qd, tau)
        msg = str(e.value)
        assert f"sample 1: link {link + 1} ({mech.names[link]})" in msg, (name, msg)
        assert f"'l{link + 1}'" in msg and "numerically singular" in msg, (name, msg)
        # the regular samples alone still answer
        assert np.isfinite(model.forward_dynamics(q[[0, 2]], qd[[0, 2]], tau[[0, 2]])).all(), name


@pytest.mark.case("W2", "W3")
@settings(max_examples=25, deadline=None, derandomize=True, database=None)
@given(
    dim=st.sampled_from([2, 3]),
    link=st.integers(0, 4),
    exponent=st.floats(-307.0, -147.0),
    tilt=st.sampled_from([0.0, 1e-5, 1e-9, 1e-13]),
    seed=st.integers(0, 2**16),
)
def test_every_short_or_tilted_rod_is_refused_naming_its_link(dim, link, exponent, tilt, seed):
    """Any rod of exo5 shorter than working precision (``l`` from 1e-307 to 1e-147 m), or in 3D tilted
    within 1e-5 rad of vertical, is refused by the fast methods naming that link (hypothesis)."""
    mech = exo5(dim)
    n = mech.nlinks
    q, qd, tau = _state(mech, seed)
    which = "l"
    if dim == 3 and tilt > 0:
        q[0, n + link] = math.copysign(math.pi / 2 - tilt, q[0, n + link])
        which = "psi"
    else:
        q[0, -n + link] = 10.0**exponent
    for name in ("newton-euler", "matrix-factored", "pinocchio"):
        with pytest.raises(SingularConfigurationError) as e:
            prepare(mech, name).forward_dynamics(q, qd, tau)
        msg = str(e.value)
        assert f"sample 0: link {link + 1} ({mech.names[link]})" in msg, (name, msg)
        assert (f"field 'l{link + 1}'" if which == "l" else f"psi{link + 1} = ") in msg, (name, msg)


@pytest.mark.case("W2")
def test_an_answer_that_overflows_is_refused_naming_sample_and_coordinate():
    """An answer that overflows float64 (picogram links pushed by ``1e299``) is refused by every method
    naming the sample, the field and the coordinate, never returned as inf or NaN."""
    mech = exo5(3)
    mech = mech.replace(masses=tuple(tuple(m * 1e-12 for m in ms) for ms in mech.masses))
    q, qd, _ = _state(mech, 3)
    tau = np.zeros_like(q)
    tau[0, 4] = 1e299
    for name, model in _models(mech).items():
        with pytest.raises(SingularConfigurationError) as e, np.errstate(all="ignore"):
            model.forward_dynamics(q, qd, tau)
        assert "sample 0: field 'qdd' coordinate" in str(e.value) and "not finite" in str(e.value), (name, str(e))


@pytest.mark.case("W2", "W3")
def _refused_state(mech, seed: int, what: str):
    """``_state`` with sample 0 made singular as ``what`` says: ``"l5=1e-300"`` (rod 5 of 1e-300 m) or
    ``"psi3=pi/2-<d>"`` (rod 3 within ``d`` rad of vertical)."""
    n = mech.nlinks
    q, qd, tau = _state(mech, seed)
    if what == "l5=1e-300":
        q[0, 2 * n + 4] = 1e-300
    else:
        q[0, n + 2] = math.pi / 2 - float(what.split("pi/2-")[1])
    return q, qd, tau


@pytest.mark.parametrize("what", ["l5=1e-300", "psi3=pi/2-1e-15"])
def test_cli_forward_refuses_in_one_line_with_exit_2(tmp_path, what):
    """``exo-bench forward`` (newton-euler, the default) refuses a rod of 1e-300 m or one within
    1e-15 rad of vertical in one line naming the sample, the link and the reason, exit 2: no
    ``null`` or 1e283 in its JSON."""
    mech = exo5(3)
    q, qd, tau = _refused_state(mech, 5, what)
    f = tmp_path / "s.json"
    f.write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "tau": tau.tolist()}))
    r = cli_process("forward", "exo5-3d", f)
    assert r.returncode == 2, (r.stdout[-300:], r.stderr[-300:])
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    link = "link 5 (trunk)" if what == "l5=1e-300" else "link 3 (swing_thigh)"
    assert "sample 0" in lines[0] and link in lines[0] and "numerically singular" in lines[0], lines[0]


# --------------------------------------------------------------------------- W3: near-vertical rods
@pytest.mark.case("W3")
@pytest.mark.parametrize("delta", [1e-8, 1e-11, 1e-15])
def test_a_rod_within_rounding_reach_of_vertical_is_refused_by_every_method(delta):
    """A rod near vertical (``psi3 = pi/2 - 1e-8``, where the methods' answers differed by up to 78.6)
    is refused by every method with one message: the sample, the link, its condition number against
    the bound, and why (its azimuth moves almost no mass)."""
    mech = exo5(3)
    n = mech.nlinks
    q, qd, tau = _state(mech, 0)
    q[0, n + 2] = math.pi / 2 - delta
    for name, model in _models(mech).items():
        with pytest.raises(SingularConfigurationError) as e:
            model.forward_dynamics(q, qd, tau)
        msg = str(e.value)
        for part in ("sample 0: link 3 (swing_thigh)", "numerically singular", "condition", "psi3", "vertical"):
            assert part in msg, (name, part, msg)


def _near_bound_state(mech, seed, factor):
    """A seeded state of 3D ``mech`` whose condition is ``factor`` times the bound: one link's rod
    tilted towards vertical, ``cos psi`` from the formula of the module docstring with cond(mu_s)
    computed densely here (the tilted angle itself, near pi/2, enters the largest angle)."""
    from exo_bench.models.runtime.conditioning import CONDITION_LIMIT

    q, qd, tau = _state(mech, seed)
    n = mech.nlinks
    rng = np.random.default_rng(seed)
    link = int(rng.integers(n))
    others = np.delete(np.abs(q[0, : 2 * n]), n + link)
    angles = max(1.0, float(others.max()), math.pi / 2)
    cos = math.sqrt(_mu_condition(mech) * angles / (factor * CONDITION_LIMIT))
    q[0, n + link] = math.acos(cos) * (1 if rng.random() < 0.5 else -1)
    return q, qd, tau, link


@pytest.mark.case("W3")
@pytest.mark.parametrize("seed", range(6))
def test_near_the_bound_answers_within_the_error_model_and_beyond_it_refuses(seed):
    """Seeded random trees with a rod tilted so that the condition is 0.3 or 3 times the bound: below
    it every method answers with a backward error within the error model, above it every method
    refuses naming the tilted link (before: every method answered whatever the condition)."""
    from exo_bench.models.runtime.conditioning import CONDITION_LIMIT

    mech = random_tree(2 + seed % 4, 3, 100 + seed)
    models = _models(mech)
    for factor, answers in ((0.3, True), (3.0, False)):
        q, qd, tau, link = _near_bound_state(mech, seed, factor)
        if answers:
            ref = models["pinocchio"].forward_dynamics(q, qd, tau)
            w = np.sqrt(np.diagonal(models["pinocchio"].mass_matrix(q), axis1=1, axis2=2))
        for name, model in models.items():
            if not answers:
                with pytest.raises(
                    SingularConfigurationError, match=f"numerically singular: sample 0: link {link + 1} "
                ):
                    model.forward_dynamics(q, qd, tau)
                continue
            qdd = model.forward_dynamics(q, qd, tau)
            assert np.isfinite(qdd).all(), name
            residual = np.abs(model.inverse_dynamics(q, qd, qdd) - tau)
            ratio = float((residual / (EPS * _backward_scale(mech, q, qd, qdd))).max())
            assert ratio <= K, (name, ratio)  # measured: at most 0.03
            if known_wrong_warning(name.split(" ")[0], mech.dim):
                continue  # eq. (18) as printed: other equations, wrong by design in 3D
            # forward error: the methods agree to K eps kappa each, in the norm equilibrated by diag(M)
            err = np.linalg.norm(w * (qdd - ref)) / np.linalg.norm(w * ref)
            assert err <= 2 * K * EPS * factor * CONDITION_LIMIT, (name, err / (EPS * factor * CONDITION_LIMIT))


def _backward_scale(mech, q, qd, qdd):
    """Per row, the error model's bound on ``|M qdd + h - tau|`` for an answer of a backward-stable
    solve: the rounding of ``ID(q, qd, qdd)`` and of ``h`` (term scales), of ``M qdd`` (``M`` derived
    by differences: ``mass_matrix_scale(derived=True)``) and the factorisation's
    ``|dM_ab| <= c eps sqrt(S_aa S_bb)`` of the equilibrated Cholesky."""
    S = mass_matrix_scale(mech, q, derived=True)
    s = np.sqrt(np.diagonal(S, axis1=1, axis2=2))
    a = np.abs(qdd)
    return (
        term_scale(mech, q, qd, qdd)
        + term_scale(mech, q, qd)
        + (S @ a[..., None])[..., 0]
        + mech.dof * s * (s * a).sum(axis=1, keepdims=True)
    )


# --------------------------------------------------------------------------- W4, T5: the derivatives
@pytest.mark.case("W4")
@pytest.mark.parametrize("what", ["l5=1e-300", "psi3=pi/2-1e-8", "psi3=pi/2-1e-15"])
def test_forward_dynamics_derivatives_refuse_where_forward_dynamics_does(what):
    """``model.derivatives.forward_dynamics`` refuses what ``forward_dynamics`` refuses, with the same
    message (before: NaN and inf at ``l5 = 1e-300``, garbage near vertical)."""
    pytest.importorskip("casadi")
    mech = exo5(3)
    q, qd, tau = _refused_state(mech, 2, what)
    model = prepare(mech, "newton-euler")
    with pytest.raises(SingularConfigurationError) as want:
        model.forward_dynamics(q, qd, tau)
    with pytest.raises(SingularConfigurationError) as got:
        model.derivatives.forward_dynamics(q, qd, tau)
    assert str(got.value) == str(want.value)


@pytest.mark.case("T5")
def test_derivatives_take_zero_samples_and_name_mismatched_fields():
    """The derivatives give empty results for 0 samples, and a ValueError naming the field, the
    expected and the actual sample count for mismatched arrays, with and without ``check`` (before:
    numpy's reshape error and CasADi's 'mismatching shape')."""
    pytest.importorskip("casadi")
    mech = exo5(3)
    d = mech.dof
    D = prepare(mech, "matrix-factored").derivatives
    z = np.zeros((0, d))
    for check in (True, False):
        out = D.forward_dynamics(z, z, z, check=check)
        assert [x.shape for x in out] == [(0, d), (0, d, d), (0, d, d), (0, d, d)]
        assert [x.shape for x in D.inverse_dynamics(z, z, z, check=check)] == [(0, d, d)] * 3
        q, qd, tau = _state(mech, 4)
        two, three = np.repeat(q, 2, axis=0), np.repeat(qd, 3, axis=0)
        with pytest.raises(ValueError, match=r"field 'qd': expected 2 samples \(as q\), got 3"):
            D.forward_dynamics(two, three, np.repeat(tau, 2, axis=0), check=check)
        with pytest.raises(ValueError, match=r"field 'tau': expected 2 samples \(as q\), got 1"):
            D.forward_dynamics(two, np.repeat(qd, 2, axis=0), tau, check=check)
        with pytest.raises(ValueError, match=r"field 'qdd': expected 2 samples \(as q\), got 3"):
            D.inverse_dynamics(two, np.repeat(qd, 2, axis=0), three, check=check)


@pytest.mark.case("T5")
def test_derivatives_of_a_massless_link_name_the_link():
    """A link that moves no mass makes the derivatives of forward dynamics refuse, naming the link,
    with and without ``check`` (a property of the mechanism, not of the states; before: NaN with
    ``check=False``)."""
    pytest.importorskip("casadi")
    mech = exo5(3)
    masses = list(mech.masses)
    masses[3] = (masses[3][0], 0.0, 0.0)
    m = mech.replace(masses=tuple(masses))
    q, qd, tau = _state(m, 6)
    D = prepare(m, "pinocchio").derivatives
    for check in (False, True):
        with pytest.raises(SingularConfigurationError, match=r"link 4 \(swing_shin\)"):
            D.forward_dynamics(q, qd, tau, check=check)
        assert np.isfinite(D.inverse_dynamics(q, qd, tau, check=check)[0]).all()  # inverse dynamics stays defined


@pytest.mark.case("W3")
@pytest.mark.parametrize("dim", [2, 3])
def test_an_angle_too_large_for_its_rounding_is_refused_naming_the_coordinate(dim):
    """An angle of 1e14 rad (whose sine carries a rounding of 0.02 rad in every method) is refused,
    naming the sample, the link and the coordinate, in 2D as in 3D."""
    mech = exo5(dim)
    q, qd, tau = _state(mech, 8)
    q[0, 1] = 1e14
    for name, model in _models(mech).items():
        with pytest.raises(SingularConfigurationError, match=r"sample 0: link 2 \(stance_thigh\): phi2 = 1"):
            model.forward_dynamics(q, qd, tau)


def test_the_bound_is_the_error_models():
    """The conditioning test's roundings per term are conftest's ``K``, and its bound is ``K eps kappa``
    at ``FORWARD_RTOL``."""
    from exo_bench.models.runtime import conditioning as c

    assert c.ROUNDINGS == K
    assert c.CONDITION_LIMIT * K * EPS == pytest.approx(c.FORWARD_RTOL)


@pytest.mark.parametrize("seed", range(8))
def test_the_o_n_estimate_of_the_mass_distributions_condition_is_its_dense_cond_1(seed):
    """The O(n) estimate (Hager's, by the tree factor) is the dense ``cond_1(mu_s)`` of conftest's
    point-mass oracle, to rounding, on seeded random trees, chains and the presets."""
    from exo_bench.models.runtime.conditioning import coupling_condition

    mech = [random_tree(3 + 7 * seed, 2 + seed % 2, seed), exo5(3)][seed == 7]
    assert coupling_condition(mech).kappa == pytest.approx(_mu_condition(mech), rel=1e-9)


def test_the_check_is_o_n_per_sample_no_n_by_n_array():
    """The check of a 3D chain of 3000 links allocates O(n) per sample: its peak (tracemalloc) stays
    within 40 doubles per coordinate and sample, where one ``n x n`` matrix would be 3000 times that."""
    import tracemalloc

    from exo_bench.models.mechanism.presets import chain

    mech = chain(3000, 3)
    model = prepare(mech, "newton-euler")
    q, _, _ = random_states(mech, 4, 1)
    model.check_regular(q)  # the mechanism's part: once, on first use
    tracemalloc.start()
    model.check_regular(q)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak <= 40 * 8 * q.size, peak
