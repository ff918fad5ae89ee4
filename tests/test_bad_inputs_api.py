"""Bad input through the library API (issue 26, items 1 and 3, and the API rows of item 6).

The command-line catalogue is tests/test_bad_inputs.py; this file holds what a caller of
``prepare(...).inverse_dynamics`` can pass that used to give silently wrong forces or crash the
interpreter:

* states in any memory layout (Fortran order from a DataFrame or ``np.asfortranarray``, strided
  views, other dtypes) give the forces of the same values in C-ordered float64, with ``check=True``;
* ``check=False`` checks no value but everything memory safety needs (dtype, C order, one shape
  for q, qd, qdd and ``out``), with a ValueError naming the field: never a read or write past an
  array, never an integer result;
* ``qd=None``/``qdd=None`` are a ValueError naming the field; zero samples give zero rows.

Each property compares a method with ITSELF on the C-ordered float64 copy of the same values: the
arithmetic is the same, so the error model (tests/conftest.py, ``k = K``) is the bound, and the
agreement of the methods with each other is held elsewhere (test_properties, test_numeric).
The oracle that would catch the old bug is independent: Pinocchio's RNEA, which always copied,
differed from the compiled kernels by 500-1300 on Fortran-ordered exo5-3d states.
"""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
from conftest import assert_forces_agree, assert_mass_matrices_agree, installed_methods
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from exo_bench import prepare
from exo_bench.api.methods import METHODS, known_wrong
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, fig2a

#: Every installed method (conftest.installed_methods) and kernel, on a 3D and a 2D mechanism (lagrange on fig2a-2d only: its
#: derivation for exo5-3d takes minutes).
_CASES = [(m, k) for m, s in METHODS.items() if m in installed_methods() for k in (s.kernel_options or (None,))]
_MODELS: dict = {}


def _model(method: str, kernel, dim: int):
    key = (method, kernel, dim)
    if key not in _MODELS:
        mech = exo5(3) if dim == 3 and method != "lagrange" else fig2a(2) if dim == 2 else fig2a(3)
        _MODELS[key] = prepare(mech, method, **({"kernel": kernel} if kernel else {}))
    return _MODELS[key]


def _call(model, *args, **kw):
    with warnings.catch_warnings():  # matrix-paper warns of its NaN in 3D by design
        warnings.simplefilter("ignore", RuntimeWarning)
        return model.inverse_dynamics(*args, **kw)


# ------------------------------------------------------------------------------ item 1: layouts
@pytest.mark.parametrize("method,kernel", _CASES, ids=[f"{m}-{k}" if k else m for m, k in _CASES])
def test_fortran_ordered_states_give_the_forces_of_pinocchio(method, kernel):
    """The reported case: a DataFrame's ``.values`` (Fortran order) gave uninitialised output from
    the compiled kernels. Checked against Pinocchio, an independent implementation."""
    if method in known_wrong():
        pytest.skip(f"{method}: {known_wrong()[method]}")
    model = _model(method, kernel, 3)
    mech = model.mechanism
    q, qd, qdd = random_states(mech, 40, seed=3)
    expected = prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)
    f = np.asfortranarray
    tau = _call(model, f(q), f(qd), f(qdd))
    assert_forces_agree(tau, expected, mech, q, qd, qdd, what=f"{method} on Fortran-ordered states")


def test_a_pandas_dataframe_is_read_by_value():
    pd = pytest.importorskip("pandas")
    mech = exo5(3)
    q, qd, qdd = random_states(mech, 30, seed=4)
    frames = [pd.DataFrame(a) for a in (q, qd, qdd)]
    model = _model("matrix-factored", "numba", 3)
    tau = model.inverse_dynamics(*frames)
    assert_forces_agree(tau, _model("pinocchio", None, 3).inverse_dynamics(q, qd, qdd), mech, q, qd, qdd)


_layout = st.sampled_from(["C", "F", "strided", "reversed"])
_dtype = st.sampled_from(["float64", "float32", "int64", ">f8"])


def _relayout(a: np.ndarray, layout: str, dtype: str) -> np.ndarray:
    a = a.astype(dtype)
    if layout == "F":
        return np.asfortranarray(a)
    if layout == "strided":  # every other row and column of a larger array
        big = np.zeros((2 * a.shape[0], 2 * a.shape[1]), dtype=a.dtype)
        big[::2, ::2] = a
        return big[::2, ::2]
    if layout == "reversed":
        return a[::-1][::-1] if a.shape[0] == 1 else np.ascontiguousarray(a[::-1])[::-1]
    return np.ascontiguousarray(a)


@settings(max_examples=40, deadline=None, derandomize=True, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    case=st.sampled_from(_CASES),
    dim=st.sampled_from([2, 3]),
    samples=st.sampled_from([1, 3, 17]),
    layouts=st.tuples(_layout, _layout, _layout),
    dtype=_dtype,
    single=st.booleans(),
    with_out=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_every_layout_and_dtype_agrees_with_the_c_ordered_float64_call(
    case, dim, samples, layouts, dtype, single, with_out, seed
):
    """Property: with ``check=True`` every model gives, for any layout, stride and real dtype of the
    states (and with or without ``out``), the forces of the C-ordered float64 call on the same values;
    with ``check=False`` it gives them for C-ordered float64 and refuses anything else with a
    ValueError naming the field (never a wrong answer, never a crash)."""
    method, kernel = case
    model = _model(method, kernel, dim)
    mech = model.mechanism
    q, qd, qdd = random_states(mech, samples, seed=seed)
    if dtype == "int64":  # integer states: the values must be exact integers
        q, qd, qdd = (np.round(a) for a in (q, qd, qdd))
        q[:, -mech.nlinks :] = np.abs(q[:, -mech.nlinks :]) + 1
    elif dtype == "float32":
        q, qd, qdd = (a.astype(np.float32).astype(np.float64) for a in (q, qd, qdd))
    args = [_relayout(a, lay, dtype) for a, lay in zip((q, qd, qdd), layouts)]
    ref_args = (q, qd, qdd)
    if single:
        args, ref_args = [a[0] for a in args], tuple(a[0] for a in ref_args)
    expected = _call(model, *ref_args)
    out = np.empty(expected.shape) if with_out else None
    tau = _call(model, *args, out=out)
    if out is not None:
        assert tau is out
    s = (lambda a: a[None]) if single else (lambda a: a)

    def agrees(got, what: str) -> None:
        """``got`` (a sample or a batch) gives the forces of the C-ordered float64 call (when they are finite)."""
        if not np.isnan(expected).any():
            assert_forces_agree(s(got), s(expected), mech, *(s(np.asarray(a)) for a in ref_args), what=what)

    assert tau.dtype == np.float64 and tau.shape == expected.shape and tau.flags.c_contiguous
    agrees(tau, f"{method} {layouts} {dtype}")
    c_float = dtype == "float64" and all(a.flags.c_contiguous for a in args)
    if c_float:
        agrees(
            _call(model, *args, check=False, out=None if out is None else np.empty_like(out)), f"{method} check=False"
        )
    else:
        with pytest.raises(ValueError, match=r"field '(q|qd|qdd)': expected C-ordered float64"):
            _call(model, *args, check=False)


# ------------------------------------------------------------------------------ item 3: check=False
def _fast_cases(mech):
    q, qd, qdd = random_states(mech, 8, seed=1)
    d = mech.dof
    return {
        "out smaller than the batch": ((q, qd, qdd), {"out": np.empty((2, d))}, "field 'out'"),
        "out of one sample for a batch": ((q, qd, qdd), {"out": np.empty(d)}, "field 'out'"),
        "out (1, dof) for one sample": ((q[0], qd[0], qdd[0]), {"out": np.empty((1, d))}, "field 'out'"),
        "out of float32": ((q, qd, qdd), {"out": np.empty(q.shape, np.float32)}, "field 'out'"),
        "out read-only": ((q, qd, qdd), {"out": np.broadcast_to(np.empty(d), q.shape)}, "field 'out'"),
        "out Fortran-ordered": ((q, qd, qdd), {"out": np.empty(q.shape, order="F")}, "field 'out'"),
        "qd with fewer samples": ((q, qd[:3], qdd), {}, "field 'qd'"),
        "qdd with more samples": ((q[:3], qd[:3], qdd), {}, "field 'qdd'"),
        "q with the wrong dof": ((q[:, :-1], qd, qdd), {}, "field 'q'"),
        "int64 states": ((q.astype(np.int64), qd.astype(np.int64), qdd.astype(np.int64)), {}, "field 'q'"),
        "a list": ((q.tolist(), qd, qdd), {}, "field 'q'"),
        "qd None": ((q, None, qdd), {}, "field 'qd'"),
        "Fortran-ordered q": ((np.asfortranarray(q), qd, qdd), {}, "field 'q'"),
        "3-D arrays": ((q[None], qd[None], qdd[None]), {}, "field 'q'"),
    }


FAST = list(_fast_cases(exo5(3)))


@pytest.mark.parametrize("method,kernel", _CASES, ids=[f"{m}-{k}" if k else m for m, k in _CASES])
@pytest.mark.parametrize("name", FAST)
def test_check_false_refuses_what_is_not_memory_safe(method, kernel, name):
    model = _model(method, kernel, 3)
    args, kw, field = _fast_cases(model.mechanism)[name]
    with pytest.raises(ValueError, match=rf"{method}: {field}: expected"):
        _call(model, *args, check=False, **kw)


def test_check_false_refusals_in_a_subprocess_do_not_crash_the_interpreter():
    """The reported crashes were heap corruption (exit 134) and SIGSEGV: run the worst cases in a
    child process so that a regression fails this test instead of killing the test run."""
    code = """
import numpy as np
from exo_bench import prepare
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5
mech = exo5(3)
q, qd, qdd = random_states(mech, 5000, seed=0)
for method in ("matrix", "matrix-factored", "recurrence"):
    m = prepare(mech, method)
    for args, kw in (((q, qd, qdd), {"out": np.empty((1, mech.dof))}),
                     ((q[0], qd[0], qdd[0]), {"out": np.empty((1, mech.dof))}),
                     ((q, qd[:10], qdd[:10]), {})):
        try:
            m.inverse_dynamics(*args, check=False, **kw)
            raise SystemExit(f"{method}: accepted")
        except ValueError:
            pass
print("ok")
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0 and r.stdout.strip() == "ok", (r.returncode, r.stdout, r.stderr[-2000:])


# ------------------------------------------------------------------------------ item 6: API rows
@pytest.mark.parametrize("method,kernel", _CASES, ids=[f"{m}-{k}" if k else m for m, k in _CASES])
def test_none_rates_are_a_value_error_naming_the_field(method, kernel):
    model = _model(method, kernel, 2)
    q, qd, qdd = random_states(model.mechanism, 2, seed=0)
    for args, field in (((q, None, qdd), "qd"), ((q, qd, None), "qdd")):
        with pytest.raises(ValueError, match=rf"field '{field}'.*got None"):
            _call(model, *args)
    with pytest.raises(ValueError, match=r"field 'qd'.*got None"):
        model.bias_forces(q, None)


@pytest.mark.parametrize("method,kernel", _CASES, ids=[f"{m}-{k}" if k else m for m, k in _CASES])
@pytest.mark.parametrize("check", [True, False])
def test_zero_samples_give_zero_rows(method, kernel, check):
    """Pinocchio's bias_forces on 0 samples used to fail with "need at least one array to stack"."""
    model = _model(method, kernel, 2)
    d = model.dof
    q = qd = qdd = np.empty((0, d))
    assert _call(model, q, qd, qdd, check=check).shape == (0, d)
    assert model.bias_forces(q, qd, check=check).shape == (0, d)
    assert model.mass_matrix(q, check=check).shape == (0, d, d)


def test_mass_matrix_and_bias_forces_take_any_layout():
    model = _model("pinocchio", None, 3)
    mech = model.mechanism
    q, qd, _ = random_states(mech, 6, seed=2)
    f = np.asfortranarray
    assert_mass_matrices_agree(model.mass_matrix(f(q)), model.mass_matrix(q), mech, q)
    assert_forces_agree(model.bias_forces(f(q), f(qd)), model.bias_forces(q, qd), mech, q, qd, np.zeros_like(q))
    with pytest.raises(ValueError, match="field 'q'"):
        model.mass_matrix(f(q), check=False)
