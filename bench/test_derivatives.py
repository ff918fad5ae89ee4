"""Derivatives of the equations of motion (issue 36): ours and the peers', error against run time.

Rows (``extra_info["method"]``), on exo5-3d and 3D chains (n of :data:`CHAIN_N` per profile: 10 and
20 in the quick one, to 300 in the full one), parametrized by a ``(method, n, dim, topology)`` case
so that the distributed sweep groups them into rows of one host (bench/perf/rows.py). The routes are
bench/perf/derivative_routes.py:

* inverse derivatives ``(dtau/dq, dtau/dqd, M)``, batched (``test_inverse_derivatives``): the
  analytic kernels ``analytic (numpy|numba|simd)``; ``model.derivatives (newton-euler)``;
  ``casadi AD`` (today's path); ``central differences (newton-euler batched)``; ``mjd_inverseFD
  (mujoco)``; ``CalcInverseDynamics AutoDiffXd (drake)``; ``computeRNEADerivatives (pinocchio)``
  (refused on mimic joints: the row is skipped with Pinocchio's own message); the baseline
  ``ID (newton-euler batched)``; and ``write floor (fill)``, the memory bandwidth floor of the output
  (``fill`` of three preallocated ``(S, dof, dof)`` arrays: no derivative can write them faster);
* one sample per call (``test_inverse_derivatives_one_sample``): ``analytic (auto)`` and ``casadi AD``
  against the baseline ``pin.rnea (bare)`` (preallocated joint arrays, as bench/test_inverse_dynamics.py);
* forward derivatives ``(dqdd/dq, dqdd/dqd, M^-1)``, batched (``test_forward_derivatives``):
  ``model.derivatives (newton-euler)``, ``casadi AD + LU``, and the baseline ``FD (newton-euler batched)``;
* the directional derivatives of inverse dynamics, batched (``test_inverse_products``): ``JVP
  (model.derivatives, KERNEL)`` (``dtau`` along seeded ``(dq, dqd, dqdd)``) and ``VJP (model.derivatives,
  KERNEL)`` (``w^T`` of the three Jacobians, seeded ``w``), the public calls with ``check=False``, KERNEL
  the products kernel that ran (``Derivatives.products_kernel``: ``simd`` for these mechanisms); the issue
  asks about 2-3x batched ID, whose row is the inverse group's (same states, same process).

**Error** against the 50-digit reference (exo_bench.lagrange.derivative_reference) on the first
:func:`_ref_count` samples: ``max_rel_err`` (``max |ours - ref|`` over the largest ``|ref|``, over the three
matrices) and, for inverse derivatives, ``err_ratio``, the error in units of the error model
(``eps * scale``, the sum of ``|terms|`` of each entry). The reference goes to n = :data:`REF_N` for
inverse derivatives and their products and :data:`REF_N_FORWARD` for forward derivatives (its cost: the module's docstring);
beyond, ``reference`` says "none". The routes that differentiate exactly (:data:`EXACT`) are held to
``K eps scale`` (asserted); finite differences are recorded. A route not built in this commit skips
with "not available in this commit" and its error; a projected batch over the profile's budget is cut
to fewer samples. Untimed (the test suite runs bench/ with ``--benchmark-disable``), only the exo5-3d
rows run, once each on 4 samples.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from exo_bench.api import prepare
from exo_bench.bench.perf import derivative_routes as routes
from exo_bench.bench.perf.profiles import current
from exo_bench.lagrange import derivative_reference as dr
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, exo5

CHAIN_N = {"quick": (10, 20), "full": (10, 20, 30, 50, 100, 200, 300)}
SAMPLES = {"quick": 64, "full": 256}
#: Seconds one timed batch may take (projected from one sample): the batch is cut to fit.
BUDGET = {"quick": 2.0, "full": 10.0}
REF_N, REF_N_FORWARD = 100, 20
CASADI_MAX_N = 100  # CasADi's preparation: 7.3 s and 26 ms per sample at n = 100 (issue 36), minutes beyond
#: Pinocchio's Data is 32 nv^3 bytes (0.87 GB at n = 100, 23 GB at 300); Drake's AutoDiffXd carries
#: 3 dof directions through every operation and MuJoCo's finite differences call mj_inverse 3 nv + 1
#: times: seconds per sample beyond n = 100.
PEER_MAX_N = {
    "computeRNEADerivatives (pinocchio)": 20,
    "pin.rnea (bare)": 50,
    "CalcInverseDynamics AutoDiffXd (drake)": 100,
    "mjd_inverseFD (mujoco)": 100,  # 0.2 s per sample at n = 20 (3 nv + 1 calls of mj_inverse, from Python)
}

INVERSE = (
    "analytic (numpy)",
    "analytic (numba)",
    "analytic (simd)",
    "model.derivatives (newton-euler)",
    "casadi AD",
    "central differences (newton-euler batched)",
    "mjd_inverseFD (mujoco)",
    "CalcInverseDynamics AutoDiffXd (drake)",
    "computeRNEADerivatives (pinocchio)",
    "ID (newton-euler batched)",
    "write floor (fill)",
)
ONE_SAMPLE = ("analytic (auto)", "casadi AD", "pin.rnea (bare)")
FORWARD = ("model.derivatives (newton-euler)", "casadi AD + LU", "FD (newton-euler batched)")
PRODUCTS = ("JVP (model.derivatives)", "VJP (model.derivatives)")
#: The module each peer's route imports (skipped where it is not installed), by the route's row name.
NEEDS = {
    "casadi AD": "casadi",  # the optional extra [casadi]: without it (the main job's default install) the rows skip
    "casadi AD + LU": "casadi",
    "mjd_inverseFD (mujoco)": "mujoco",
    "CalcInverseDynamics AutoDiffXd (drake)": "pydrake",
    "computeRNEADerivatives (pinocchio)": "pinocchio",
}
#: Routes that differentiate exactly (no step): their error is ASSERTED within the error model,
#: ``K eps scale`` with K of tests/conftest.py (finite differences are recorded, not asserted).
EXACT = ("analytic", "model.derivatives", "casadi AD", "CalcInverseDynamics", "JVP", "VJP")
K = 8
UNTIMED = (
    "derivatives: the chains are measured when the benchmarks are timed (exo-bench bench); untimed "
    "(the test suite), each route runs once on exo5-3d and its error is checked"
)


def _mech(n: int, topology: str):
    return exo5(3) if topology == "exo5" else chain(n, 3)


def _cases(methods, sw):
    sizes = [(5, "exo5")] + [(n, "chain") for n in CHAIN_N[sw.name]]
    return [(m, n, 3, t) for n, t in sizes for m in methods]


def pytest_generate_tests(metafunc):
    if "case" not in metafunc.fixturenames:
        return
    sw = current(metafunc.config.getoption("--sweep"))
    methods = {
        "test_inverse_derivatives": INVERSE,
        "test_inverse_derivatives_one_sample": ONE_SAMPLE,
        "test_forward_derivatives": FORWARD,
        "test_inverse_products": PRODUCTS,
    }[metafunc.function.__name__]
    cases = _cases(methods, sw)
    ids = [f"{m.replace(' ', '')}-{'exo5' if t == 'exo5' else f'chain{n}'}-3d" for m, n, _, t in cases]
    metafunc.parametrize("case", cases, ids=ids)


@pytest.fixture(scope="module")
def references():
    """The 50-digit references of this module's run, computed once per (mechanism, kind)."""
    return {}


def _ref_count(n: int) -> int:
    return 2 if n <= 10 else 1


def _reference(references, mech, q, qd, x, forward: bool):
    limit = REF_N_FORWARD if forward else REF_N
    if mech.nlinks > limit:
        return None
    k = _ref_count(mech.nlinks)
    key = (mech, forward, *(a[:k].tobytes() for a in (q, qd, x)))
    if key not in references:
        if forward:
            references[key] = (dr.forward_derivatives(mech, q[:k], qd[:k], x[:k])[1:], None)
        else:
            refs = dr.inverse_derivatives(mech, q[:k], qd[:k], x[:k])
            references[key] = (refs, dr.derivative_scale(mech, q[:k], qd[:k], x[:k]))
    return references[key]


def _untimed(benchmark, topology: str, sweep) -> int:
    """Samples per batch: the profile's, or 4 on exo5-3d alone when the benchmarks are not timed."""
    if not benchmark.disabled:
        return SAMPLES[sweep.name]
    if topology != "exo5":
        pytest.skip(UNTIMED)
    return 4


def _check_error(method: str, errors: dict) -> None:
    if method.startswith(EXACT) and errors["reference"].startswith("50-digit"):
        assert errors["err_ratio"] <= K, f"{method}: error {errors['err_ratio']:.2f} eps * scale > {K}"


def _errors(got, ref) -> dict:
    if ref is None:
        return {
            "reference": "none (n beyond the reference's reach)",
            "max_rel_err": float("nan"),
            "err_ratio": float("nan"),
        }
    refs, scales = ref
    k = refs[0].shape[0]
    rel = max(dr.max_relative_error(a[:k], b) for a, b in zip(got, refs))
    ratio = max(dr.error_ratio(a[:k], b, s) for a, b, s in zip(got, refs, scales)) if scales else float("nan")
    return {"reference": f"50-digit d'Alembert dual numbers, {k} sample(s)", "max_rel_err": rel, "err_ratio": ratio}


def _route(method: str, mech, forward: bool):
    """``(call, source)`` of a row, or a skip saying why it has none here."""
    if method in NEEDS:
        pytest.importorskip(NEEDS[method])
    if "casadi" in method and mech.nlinks > CASADI_MAX_N:
        pytest.skip(
            f"{method} n={mech.nlinks}: not run beyond n = {CASADI_MAX_N} (preparation 7.3 s at n = 100, issue 36)"
        )
    if mech.nlinks > PEER_MAX_N.get(method, 10**9):
        pytest.skip(f"{method} n={mech.nlinks}: not run beyond n = {PEER_MAX_N[method]} (bench/test_derivatives.py)")
    if method.startswith("analytic"):
        try:
            return routes.analytic(mech, method.split("(")[1].rstrip(")")), "exo_bench.models.newton_euler.derivatives"
        except ImportError as e:
            pytest.skip(f"{method}: not available in this commit ({e})")
    if method == "model.derivatives (newton-euler)":
        call, source = routes.model_derivatives(mech, "newton-euler", forward)
        if source.startswith("CasADi"):
            pytest.skip(f"{method}: not available in this commit: it is still CasADi's (source: {source[:60]}...)")
        return call, source
    table = {
        "casadi AD": lambda: routes.casadi_inverse(mech),
        "casadi AD + LU": lambda: routes.casadi_forward(mech),
        "central differences (newton-euler batched)": lambda: routes.central_differences(mech),
        "mjd_inverseFD (mujoco)": lambda: routes.mujoco_inverse_fd(mech),
        "CalcInverseDynamics AutoDiffXd (drake)": lambda: routes.drake_autodiff(mech),
        "computeRNEADerivatives (pinocchio)": lambda: routes.pinocchio_rnea_derivatives(mech),
    }
    return table[method](), method


def _first_call(method, call, args):
    """One untimed call on one sample (JIT, caches); a route that refuses or is not built skips."""
    try:
        t0 = time.perf_counter()
        call(*(a[:1] for a in args))
        return time.perf_counter() - t0
    except (ValueError, RuntimeError, NotImplementedError) as e:
        verb = "refused" if "pinocchio" in method else "not available in this commit"
        pytest.skip(f"{method}: {verb}: {type(e).__name__}: {e}")


def _timed(benchmark, sweep, method, call, args, info):
    """The batched call on as many samples as the profile's budget allows, timed; its result."""
    call(*(a[:1] for a in args))  # second call: first-call costs are gone
    t0 = time.perf_counter()
    call(*(a[:1] for a in args))
    one = max(time.perf_counter() - t0, 1e-9)
    samples = int(max(1, min(args[0].shape[0], BUDGET[sweep.name] / one)))
    args = tuple(a[:samples] for a in args)
    rounds = max(3, min(20, int(2.0 / (one * samples))))
    benchmark.extra_info.update(info, samples=samples, batched=True)
    return benchmark.pedantic(call, args=args, rounds=rounds, iterations=1, warmup_rounds=1)


def _states(mech, samples, sweep=None):
    """Seeded states; a batch is capped so that its three ``(S, dof, dof)`` results take at most the
    profile's ``array_bytes`` (6 samples at n = 300)."""
    if sweep is not None:
        samples = int(max(1, min(samples, sweep.array_bytes // (3 * 8 * mech.dof**2))))
    return random_states(mech, samples, seed=mech.nlinks)


def _info(method, n, topology, mech, what, source=""):
    return dict(method=method, n=n, dim=3, topology=topology, mechanism=mech.name, what=what, source=source)


def _derivative_row(benchmark, sweep, references, case, mech, args, forward: bool) -> None:
    """Prepare a route, time it batched, and record its error against the reference."""
    method, n, _, topology = case
    t0 = time.perf_counter()
    call, source = _route(method, mech, forward=forward)
    prep = time.perf_counter() - t0 + _first_call(method, call, args)
    info = _info(method, n, topology, mech, "forward" if forward else "inverse", source) | {"prepare_s": prep}
    got = _timed(benchmark, sweep, method, call, args, info)
    assert all(np.isfinite(g).all() for g in got), f"{method}: NaN/Inf in the derivatives"
    q, qd, x = args
    errors = _errors(got, _reference(references, mech, q, qd, x, forward=forward))
    benchmark.extra_info.update(errors)
    if not forward:
        _check_error(method, errors)
    if getattr(call, "warnings", None):  # MuJoCo's, collected by the route
        benchmark.extra_info["engine_warnings"] = "; ".join(sorted(set(call.warnings)))[:300]


def test_inverse_derivatives(benchmark, sweep, references, case):
    method, n, dim, topology = case
    benchmark.group = "derivatives-inverse-batched"
    mech = _mech(n, topology)
    q, qd, qdd = _states(mech, _untimed(benchmark, topology, sweep), sweep)
    if method == "ID (newton-euler batched)":
        model = prepare(mech, "newton-euler")
        call = lambda q, qd, qdd: model.inverse_dynamics(q, qd, qdd, check=False)  # noqa: E731
        _timed(benchmark, sweep, method, call, (q, qd, qdd), _info(method, n, topology, mech, "ID"))
        return
    if method == "write floor (fill)":
        _timed(
            benchmark, sweep, method, routes.write_floor(mech), (q, qd, qdd), _info(method, n, topology, mech, "fill")
        )
        return
    _derivative_row(benchmark, sweep, references, case, mech, (q, qd, qdd), forward=False)


def test_inverse_derivatives_one_sample(benchmark, sweep, references, case):
    method, n, dim, topology = case
    benchmark.group = "derivatives-inverse-one-sample"
    mech = _mech(n, topology)
    samples = _untimed(benchmark, topology, sweep)
    q, qd, qdd = (x[:1] for x in _states(mech, samples, sweep))  # the batch's first: one reference
    info = _info(method, n, topology, mech, "inverse") | {"samples": 1, "batched": False}
    if method == "pin.rnea (bare)":
        pytest.importorskip("pinocchio")
        if n > PEER_MAX_N[method]:
            pytest.skip(f"{method} n={n}: not run beyond n = {PEER_MAX_N[method]} (its Data is 32 nv^3 bytes)")
        import pinocchio as pin

        model = prepare(mech, "pinocchio")
        qj, vj, aj = (np.ascontiguousarray(x[0] @ model.GT) for x in (q, qd, qdd))
        pm, data = model.pin_model, model.pin_model.createData()
        benchmark.extra_info.update(info, what="rnea")
        benchmark.pedantic(lambda: pin.rnea(pm, data, qj, vj, aj), rounds=20, iterations=200, warmup_rounds=1)
        return
    call, source = _route("casadi AD" if method == "casadi AD" else method, mech, forward=False)
    one = [x[0] for x in (q, qd, qdd)]
    out = tuple(np.empty((mech.dof, mech.dof)) for _ in range(3))
    args = (*one, out) if method.startswith("analytic") else one
    try:
        call(*args)
    except (ValueError, RuntimeError) as e:
        pytest.skip(f"{method}: not available in this commit: {type(e).__name__}: {e}")
    benchmark.extra_info.update(info, source=source)
    got = benchmark.pedantic(call, args=args, rounds=20, iterations=20 if mech.dof > 60 else 200, warmup_rounds=1)
    got = tuple(np.asarray(g)[None] for g in (out if method.startswith("analytic") else got))
    errors = _errors(got, _reference(references, mech, q, qd, qdd, forward=False))
    benchmark.extra_info.update(errors)
    _check_error(method, errors)


def test_forward_derivatives(benchmark, sweep, references, case):
    method, n, dim, topology = case
    benchmark.group = "derivatives-forward-batched"
    mech = _mech(n, topology)
    q, qd, qdd = _states(mech, _untimed(benchmark, topology, sweep), sweep)
    ne = prepare(mech, "newton-euler")
    tau = ne.inverse_dynamics(q, qd, qdd, check=False)
    if method == "FD (newton-euler batched)":
        call = lambda q, qd, tau: ne.forward_dynamics(q, qd, tau, check=False)  # noqa: E731
        _timed(benchmark, sweep, method, call, (q, qd, tau), _info(method, n, topology, mech, "FD"))
        return
    _derivative_row(benchmark, sweep, references, case, mech, (q, qd, tau), forward=True)


def _product_errors(got, ref, v, jvp: bool) -> dict:
    """A product's error against the products of the 50-digit Jacobians (rounded to float64) with the same
    directions ``v``. Error model: each Jacobian entry carries at most ``K eps s_ij`` (``s`` its
    :func:`~exo_bench.lagrange.derivative_reference.derivative_scale`) and the sums of the product add
    ``eps`` per level of their terms ``|J_ij v_j|``, so a product entry carries at most ``K eps sum_j
    s_ij |v_j|`` (transposed for the VJP): ``err_ratio`` is in those units."""
    if ref is None:
        return _errors(got, None)
    (jq, jqd, M), scales = ref
    k = jq.shape[0]
    if jvp:
        refs = (sum(np.einsum("sij,sj->si", J, x[:k]) for J, x in zip((jq, jqd, M), v)),)
        units = (sum(np.einsum("sij,sj->si", S, np.abs(x[:k])) for S, x in zip(scales, v)),)
        got = (got,)
    else:
        refs = tuple(np.einsum("si,sij->sj", v[0][:k], J) for J in (jq, jqd, M))
        units = tuple(np.einsum("si,sij->sj", np.abs(v[0][:k]), S) for S in scales)
    rel = max(dr.max_relative_error(a[:k], b) for a, b in zip(got, refs))
    ratio = max(dr.error_ratio(a[:k], b, u) for a, b, u in zip(got, refs, units))
    return {"reference": f"50-digit Jacobians times the directions, {k} sample(s)", "max_rel_err": rel,
            "err_ratio": ratio}  # fmt: skip


def test_inverse_products(benchmark, sweep, references, case):
    method, n, dim, topology = case
    benchmark.group = "derivatives-products-batched"
    mech = _mech(n, topology)
    # not capped by the profile's array_bytes: that cap is for three (S, dof, dof) results; a product's are
    # (S, dof) (at n = 300 the cap left 6 samples, a partial SIMD block); the time budget still cuts the batch
    q, qd, qdd = _states(mech, _untimed(benchmark, topology, sweep))
    rng = np.random.default_rng(mech.nlinks)
    jvp = method.startswith("JVP")
    v = tuple(rng.normal(size=q.shape) for _ in range(3 if jvp else 1))
    d = prepare(mech, "newton-euler").derivatives
    call = d.inverse_dynamics_jvp if jvp else d.inverse_dynamics_vjp
    route = lambda *a: call(*a, check=False)  # noqa: E731
    args = (q, qd, qdd, *v)
    prep = _first_call(method, route, args)
    name = f"{method[:-1]}, {d.products_kernel})"  # names say what runs: "JVP (model.derivatives, simd)"
    info = _info(name, n, topology, mech, "JVP" if jvp else "VJP", d.source) | {"prepare_s": prep}
    got = _timed(benchmark, sweep, method, route, args, info)
    assert all(np.isfinite(g).all() for g in (got if isinstance(got, tuple) else (got,))), f"{method}: NaN/Inf"
    errors = _product_errors(got, _reference(references, mech, q, qd, qdd, forward=False), v, jvp)
    benchmark.extra_info.update(errors)
    _check_error(method, errors)
