"""The step NLP's exact derivatives (bench/studies/step/transcription.py, issue 36) against differences.

The transcription gives IPOPT the constraint Jacobian, the objective's gradient and the Lagrangian's
Hessian assembled from one collocation point's symbolic derivatives (mapped over the points) and the
linear part's constant ``J_Y``. Oracle: central differences of the NLP's own ``g`` and ``f`` (CasADi
evaluations of the same expressions, no derivative code shared), at the stored step, in the columns of
collocation points (the first, a midpoint, the last) and of the duration ``T``.

Error model of the fourth-order central difference ``(-g(x+2d) + 8 g(x+d) - 8 g(x-d) + g(x-2d)) / 12d``:
truncation ``d^4 / 30 |g^(5)|`` plus rounding ``18/12 eps |g| / d`` (each evaluation rounds ``|g|`` to
``eps |g|``). With ``d = 1e-4 (1 + |x_j|)`` (``|x_j| < 3`` here) and ``|g^(5)|``, ``|g|`` bounded by the
scale ``S`` of the quantities in a row (N, N m, m, rad: under 1e4 here), the error is under ``1e-14 S +
1e-11 S``: the bound asserted is ``1e-9 (1 + S_i)``, with ``S_i`` the largest of ``|g_i|`` and the row's
derivative entries (for the Hessian, times ``1 + max |lam|``), 100x the model. A Jacobian without the
points' part, or a Hessian off by one part in 1e5, fails it (asserted below).
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.bench.studies.step import data
from exo_bench.models.mechanism.presets import exo5

ca = pytest.importorskip("casadi")

from exo_bench.bench.studies.step import problem, transcription  # noqa: E402

#: Relative step of the differences, and the bound's factor (module docstring).
STEP, FACTOR = 1e-4, 1e-9


@pytest.fixture(scope="module", params=(2, 3), ids=lambda d: f"{d}d")
def nlp(request):
    mech = exo5(request.param)
    st = data.load(mech.name)
    point = problem._point_function(mech, transcription.inverse_dynamics_function(mech))
    tr = transcription.build(mech, st.settings, point)
    x = tr.x0(st.duration, st.q, st.qd, st.qdd)
    return tr, x


def _columns(tr, names: tuple[str, ...] = ("first", "midpoint", "last")) -> np.ndarray:
    """The columns of the points named, and of ``T``."""
    lay = tr.layout
    nodes = [{"first": 0, "midpoint": lay.K // 2 | 1, "last": lay.K - 1}[k] for k in names]
    return np.array([k * lay.nz + j for k in nodes for j in range(lay.nz)] + [lay.nx - 1])


def _differences(fun, x: np.ndarray, cols: np.ndarray) -> np.ndarray:
    out = []
    for j in cols:
        d = STEP * (1 + abs(x[j]))
        at = []
        for k in (2, 1, -1, -2):
            xk = x.copy()
            xk[j] += k * d
            at.append(np.asarray(fun(xk), dtype=float).ravel())
        out.append((-at[0] + 8 * at[1] - 8 * at[2] + at[3]) / (12 * d))
    return np.stack(out, axis=1)


def _bound(values: np.ndarray, J: np.ndarray) -> np.ndarray:
    """``1e-9 (1 + S_i)`` per row (module docstring)."""
    return FACTOR * (1 + np.maximum(np.abs(values), np.abs(J).max(axis=1)))


def test_constraint_jacobian_equals_central_differences(nlp):
    tr, x = nlp
    g_fun = ca.Function("g", [tr.nlp["x"]], [tr.nlp["g"]])
    g, J = tr.derivatives["jac_g"](x, [])
    g = np.asarray(g).ravel()
    assert np.array_equal(g, np.asarray(g_fun(x)).ravel())
    cols = _columns(tr)
    Jc = np.asarray(ca.DM(J)[:, [int(c) for c in cols]])
    bound = _bound(g, Jc)
    err = np.abs(_differences(g_fun, x, cols) - Jc)
    assert np.all(err <= bound[:, None]), (err / bound[:, None]).max()
    # the points' part is tested: it has entries far above the bound, in more rows than there are columns
    nz = tr.layout.nz
    structural = np.abs(tr.derivatives["jac_g"].sparsity_out(1).nnz())
    assert np.abs(Jc[:, : 3 * nz]).max() > 1e3 * bound.max() and structural > 5 * tr.layout.nx


def test_objective_gradient_equals_central_differences(nlp):
    tr, x = nlp
    f_fun = ca.Function("f", [tr.nlp["x"]], [tr.nlp["f"]])
    f, grad = (np.asarray(v, dtype=float).ravel() for v in tr.derivatives["grad_f"](x, []))
    cols = _columns(tr)
    bound = FACTOR * (1 + max(abs(f[0]), np.abs(grad).max()))
    assert np.all(np.abs(_differences(f_fun, x, cols)[0] - grad[cols]) <= bound)
    assert np.abs(grad[cols]).max() > 1e3 * bound


def test_lagrangian_hessian_equals_differences_of_its_gradient(nlp):
    """With seeded multipliers of the size IPOPT's take here (|lam| < 10), ``hess_lag`` against the
    differences of ``sigma grad f + J^T lam`` (both checked above), in a midpoint's columns and ``T``'s;
    the upper triangle is given, the lower one is empty (IPOPT mirrors it)."""
    tr, x = nlp
    lam = np.random.default_rng(36).uniform(-10, 10, len(tr.lbg))
    sigma = 1.7
    jac, grad_f = tr.derivatives["jac_g"], tr.derivatives["grad_f"]

    def lagrangian_gradient(xv):
        J = jac(xv, [])[1]
        return sigma * np.asarray(grad_f(xv, [])[1]).ravel() + np.asarray(ca.mtimes(J.T, ca.DM(lam))).ravel()

    cols = _columns(tr, ("midpoint",))
    H = ca.DM(tr.derivatives["hess_lag"](x, [], sigma, lam))
    assert H.sparsity().is_triu()
    H = np.asarray(H.full())
    H = H + np.triu(H, 1).T
    Hc = H[:, cols]
    bound = _bound(lagrangian_gradient(x), Hc) * (1 + np.abs(lam).max())
    err = np.abs(_differences(lagrangian_gradient, x, cols) - Hc)
    assert np.all(err <= bound[:, None]), (err / bound[:, None]).max()
    assert 1e-5 * np.abs(Hc[cols[:-1]]).max() > bound.max()  # one part in 1e5 of the point's Hessian is seen
