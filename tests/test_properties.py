"""Property-based tests (hypothesis): random mechanisms and states, every method through ``prepare``.

Mechanisms: trees of 1 to 5 links (random parents, several roots), branch signs, masses with zeros
(a link may carry nothing of its own), fractions near 0 and 1, dim 2 and 3. States: angles up to
two turns, near-vertical rods (``psi`` within 1e-9 of +-pi/2, and exactly the float nearest), rod
lengths exactly zero or tiny, rates up to 30 rad/s.

Properties:

* **agreement**: matrix, matrix-factored and recurrence against Pinocchio's RNEA (and Lagrange for
  n <= 2) within the error model of tests/conftest.py;
* **power balance, exactly at one state**: ``tau . qd = sum_b m_b v_b . (a_b + g up)`` with the
  point masses' velocities and accelerations computed here from the unit vectors' derivatives
  (no difference stencil);
* **M**: symmetric; ``D^-1/2 M D^-1/2`` (``D = diag M``) has the eigenvalues of the equilibrated
  mass coupling ``mu`` (each ``dim`` times) wherever :func:`exo_bench.models.mechanism.singularity.singular_reasons`
  finds nothing (positive definite, the null space empty), and where it names a link, the
  columns it names are zero (the null space is there).

Deterministic and fast in CI: a derandomized profile (``derandomize=True``, no database: the same
examples on every run) plus explicit ``@example`` edge cases.
"""

from __future__ import annotations

import math

import numpy as np
from conftest import EPS, K, assert_close, assert_forces_agree, mass_coupling_oracle, mass_matrix_scale, term_scale
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

from exo_bench import prepare
from exo_bench.models.mechanism.singularity import singular_reasons
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import split

PROFILE = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
SAMPLES = 4
LAGRANGE_MAX_LINKS = 2


def _mostly(regular, *edges, weight=5):
    """``regular`` ``weight`` times as often as each edge case (so that most examples are regular)."""
    return st.one_of(*([regular] * weight), *edges)


mass = _mostly(st.floats(0.01, 5.0), st.just(0.0), weight=3)
fraction = st.one_of(st.sampled_from([1e-6, 0.5, 1 - 1e-6]), st.floats(0.01, 0.99))


@st.composite
def mechanisms(draw, max_links=5):
    n = draw(st.integers(1, max_links))
    dim = draw(st.sampled_from([2, 3]))
    parent = [-1] + [draw(st.integers(-1, i - 1)) for i in range(1, n)]
    sign = [draw(st.sampled_from([1, -1])) for _ in range(n)]
    masses = [tuple(draw(mass) for _ in range(3)) for _ in range(n)]
    if all(x == 0 for m in masses for x in m):
        masses[-1] = (0.0, 0.0, 1.0)
    frac = [draw(fraction) for _ in range(n)]
    return Mechanism(
        dim=dim, g=9.81, parent=tuple(parent), sign=tuple(sign), masses=tuple(masses), n=tuple(frac), name="hypothesis"
    )


@st.composite
def states(draw, mech: Mechanism):
    n, dim = mech.nlinks, mech.dim
    rows = []
    for _ in range(SAMPLES):
        angle = st.floats(-4 * math.pi, 4 * math.pi)
        phi = [draw(angle) for _ in range(n)]
        psi = (
            [
                draw(
                    _mostly(
                        st.floats(-1.5, 1.5),
                        st.sampled_from([math.pi / 2, -math.pi / 2]),
                        st.floats(-1e-9, 1e-9).map(lambda d: math.pi / 2 + d),
                    )
                )
                for _ in range(n)
            ]
            if dim == 3
            else []
        )
        l = [draw(_mostly(st.floats(0.05, 2.0), st.just(0.0), st.floats(1e-9, 1e-6))) for _ in range(n)]
        rate = st.floats(-30.0, 30.0)
        qd = [draw(rate) for _ in range(mech.dof)]
        qdd = [draw(rate) for _ in range(mech.dof)]
        rows.append((phi + psi + l, qd, qdd))
    return tuple(np.array([r[k] for r in rows], dtype=float) for k in range(3))


@st.composite
def cases(draw):
    mech = draw(mechanisms())
    return mech, *draw(states(mech))


CHAIN3 = Mechanism(
    dim=3,
    g=9.81,
    parent=(-1, 0, 1),
    sign=(1, -1, 1),
    masses=((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 2.0, 1.0)),
    n=(0.5, 0.5, 0.5),
    name="massless-links",
)
VERTICAL = np.array([[0.3, -2.0, 1.1, math.pi / 2, -math.pi / 2, 0.2, 1.0, 0.0, 1e-9]])
EXAMPLE_RATES = np.full((1, 9), 25.0)


def _models(mech):
    names = ["pinocchio", "matrix", "matrix-factored", "recurrence"]
    if mech.nlinks <= LAGRANGE_MAX_LINKS:
        names.append("lagrange")
    return {name: prepare(mech, name) for name in names}


@PROFILE
@given(cases())
@example((CHAIN3, VERTICAL, EXAMPLE_RATES, -EXAMPLE_RATES))
def test_all_methods_agree(case):
    mech, q, qd, qdd = case
    models = _models(mech)
    ref = models.pop("pinocchio").inverse_dynamics(q, qd, qdd)
    for name, model in models.items():
        assert_forces_agree(model.inverse_dynamics(q, qd, qdd), ref, mech, q, qd, qdd, what=name)


def _unit_vector_derivatives(mech, q):
    """``u`` and its derivatives per link, ``(S, n, 3)`` each (2D in the plane z = 0)."""
    phi, psi, _ = split(mech, q)
    psi = np.zeros_like(phi) if psi is None else psi
    cf, sf, cp, sp = np.cos(phi), np.sin(phi), np.cos(psi), np.sin(psi)
    z = np.zeros_like(phi)
    v = lambda x, y, w: np.stack([x, y, w], -1)
    return {
        "u": v(cp * cf, cp * sf, sp),
        "f": v(-cp * sf, cp * cf, z),
        "p": v(-sp * cf, -sp * sf, cp),
        "ff": v(-cp * cf, -cp * sf, z),
        "pp": v(-cp * cf, -cp * sf, -sp),
        "fp": v(sp * sf, -sp * cf, z),
    }


def _point_mass_power(mech, q, qd, qdd):
    """``sum_b m_b v_b . (a_b + g up)``, the rate of T + Pi, from the kinematics of the point masses:
    ``w_i = s_i l_i u_i``, point ``b`` of link ``k`` at ``sum_{a in anc(k)} w_a + f_b w_k``."""
    n, dim = mech.nlinks, mech.dim
    U = _unit_vector_derivatives(mech, q)
    (phi, psi, l), (wd, pd, ld), (wdd, pdd, ldd) = (split(mech, x) for x in (q, qd, qdd))
    if psi is None:
        pd = pdd = np.zeros_like(wd)
    e = lambda x: x[..., None]
    s = np.array(mech.sign, dtype=float)[None, :, None]
    w1 = s * (e(l) * (U["f"] * e(wd) + U["p"] * e(pd)) + U["u"] * e(ld))
    w2 = s * (
        e(l) * (U["f"] * e(wdd) + U["p"] * e(pdd) + U["ff"] * e(wd**2) + U["pp"] * e(pd**2) + 2 * U["fp"] * e(wd * pd))
        + U["u"] * e(ldd)
        + 2 * (U["f"] * e(wd) + U["p"] * e(pd)) * e(ld)
    )
    up = np.zeros(3)
    up[1 if dim == 2 else 2] = 1.0
    power = np.zeros(q.shape[0])
    for k in range(n):
        anc = list(mech.ancestors[k])
        for m, f in zip(mech.masses[k], (0.0, mech.n[k], 1.0)):
            v = w1[:, anc].sum(axis=1) + f * w1[:, k]
            a = w2[:, anc].sum(axis=1) + f * w2[:, k]
            power += m * (v * (a + mech.g * up)).sum(-1)
    return power


@PROFILE
@given(cases())
@example((CHAIN3, VERTICAL, EXAMPLE_RATES, -EXAMPLE_RATES))
def test_power_balance_holds_exactly_at_every_state(case):
    """``tau . qd`` is the rate of the energy; the bound is the error model's, weighted by ``|qd|``."""
    mech, q, qd, qdd = case
    power = _point_mass_power(mech, q, qd, qdd)
    scale = (term_scale(mech, q, qd, qdd) * np.abs(qd)).sum(axis=1)
    for name, model in _models(mech).items():
        assert_close((model.inverse_dynamics(q, qd, qdd) * qd).sum(axis=1), power, scale, what=name)


def _equilibrated_eigenvalues(A):
    d = np.sqrt(np.diagonal(A, axis1=-2, axis2=-1))
    return np.linalg.eigvalsh(A / d[..., :, None] / d[..., None, :])


@PROFILE
@given(cases())
@example((CHAIN3, VERTICAL, EXAMPLE_RATES, -EXAMPLE_RATES))
def test_mass_matrix_is_symmetric_psd_with_its_null_space_where_singular_reasons_says(case):
    mech, q, _, _ = case
    n, dim = mech.nlinks, mech.dim
    reasons = singular_reasons(mech, q)
    mu, _ = mass_coupling_oracle(mech)
    for name, model in _models(mech).items():
        M = model.mass_matrix(q)
        scale = mass_matrix_scale(mech, q, derived=not model.native_terms)
        assert_close(M, np.swapaxes(M, 1, 2), scale + np.swapaxes(scale, 1, 2), what=f"{name}: symmetric")
        for s in range(q.shape[0]):
            err = K * EPS * scale[s]
            # PSD: no eigenvalue below minus the norm of the rounding (Weyl)
            assert np.linalg.eigvalsh(M[s])[0] >= -np.linalg.norm(err), name
            resolved = (np.diagonal(M[s]) > np.diagonal(err)).all()  # every diagonal above its rounding
            event("singular" if reasons[s] else "regular, resolved" if resolved else "regular, below rounding")
            if not reasons[s] and resolved:
                # M = J^T (mu (x) I) J: equilibrated, it is orthogonally similar to the equilibrated mu
                # (x) I_dim (models/simulation/forward_dynamics.py), so it has mu's eigenvalues, all positive.
                # (Not resolved: a rod of 1e-9 m at 1e-9 rad from vertical, M_phiphi ~ 1e-36, below
                # what M derived by differences can resolve; the PSD bound above still holds.)
                d = np.sqrt(np.diagonal(M[s]))
                weyl = np.linalg.norm(err / d[:, None] / d[None, :])
                want = np.sort(np.repeat(_equilibrated_eigenvalues(mu), dim))
                assert np.abs(_equilibrated_eigenvalues(M[s]) - want).max() <= weyl + K * EPS * n, name
                # positive definite; the computed M is certified so wherever its rounding (weyl) is
                # below the smallest eigenvalue (not at rods of 1e-9 m with M derived by differences)
                assert want[0] > 0, name
            elif reasons[s]:
                # each named cause leaves these columns of M zero (their coordinates move no mass)
                phi, psi, l = split(mech, q[s : s + 1])
                for i in range(n):
                    zero = []
                    if mu[i, i] == 0 or l[0, i] == 0:
                        zero = [i] + ([n + i] if dim == 3 else [])  # the angles of link i
                        if mu[i, i] == 0:
                            zero.append(mech.dof - n + i)  # and its length
                    elif psi is not None and abs(math.cos(psi[0, i])) <= 1e-15:
                        zero = [i]  # the azimuth of a vertical rod
                    for a in zero:
                        assert any(f"link {i + 1} " in r for r in reasons[s]), (name, i, reasons[s])
                        # the column is l_i cos psi_i (or 0) times at most the scale of an entry
                        assert np.abs(M[s][:, a]).max() <= K * EPS * scale[s][:, a].max() + 1e-15 * scale[s].max(), (
                            name,
                            a,
                        )
