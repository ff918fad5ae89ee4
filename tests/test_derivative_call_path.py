"""The public derivative calls, one way through (issue 47): validated once at the edge, then the kernel.

* **Counted, not timed.** ``sys.setprofile`` counts the project's own Python functions (frames whose file
  lies in a package folder: models/, matrix_method/, lagrange/, bench/, exo_bench/) that one public call
  runs on exo5-3d, one sample and a batch of 1,000, checked and not: at most :data:`MOST` (before: 63 for
  one sample, 77 for a batch, in 12 files, the states validated twice). A numba kernel entered through its
  dispatcher is counted too (numba reports it to the profiler as a call of its Python function).
* **No upward injection.** ``model.derivatives`` works on a prepared model made without ``exo_bench.api``
  (before: a ValueError until api registered its provider), with its source from the class's facts.
* **The compiled one-sample entry** answers with the bits of its row in a batch and refuses what the edge
  refuses, naming the field or the link; ``check=False`` takes plain arrays only (models/states/array_gate.py) and
  never lets an ``np.matrix`` reach a kernel.
"""

from __future__ import annotations

import importlib
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from exo_bench import prepare, presets
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.singularity import SingularConfigurationError

#: The most own Python functions a public derivative call may run to reach its kernel (issue 47's goal).
MOST = 8
SAMPLES = 1000
PACKAGES = ("exo_bench", "exo_bench.models", "exo_bench.matrix_method", "exo_bench.lagrange", "exo_bench.bench")
FOLDERS = tuple(str(Path(p).resolve()) + "/" for name in PACKAGES for p in importlib.import_module(name).__path__)
MECH = presets.exo5(dim=3)


def own_calls(f) -> Counter:
    """The project's own functions that ``f()`` runs, by ``(file, function)``, counted by ``sys.setprofile``."""
    seen: Counter = Counter()

    def profile(frame, event, arg):
        if event == "call":
            file = str(Path(frame.f_code.co_filename).resolve())
            if file.startswith(FOLDERS):
                seen[(Path(file).name, frame.f_code.co_name)] += 1

    sys.setprofile(profile)
    try:
        f()
    finally:
        sys.setprofile(None)
    return seen


@pytest.fixture(scope="module")
def exo():
    q, qd, qdd = random_states(MECH, SAMPLES, 47)
    model = prepare(MECH, "matrix-factored")
    tau = model.inverse_dynamics(q, qd, qdd)
    w = np.ascontiguousarray(qd[::-1])
    return model.derivatives, q, qd, qdd, tau, w


CALLS = {
    "inverse_dynamics": lambda D, q, qd, qdd, tau, w, c: D.inverse_dynamics(q, qd, qdd, check=c),
    "forward_dynamics": lambda D, q, qd, qdd, tau, w, c: D.forward_dynamics(q, qd, tau, check=c),
    "inverse_dynamics_jvp": lambda D, q, qd, qdd, tau, w, c: D.inverse_dynamics_jvp(q, qd, qdd, w, qd, qdd, check=c),
    "inverse_dynamics_vjp": lambda D, q, qd, qdd, tau, w, c: D.inverse_dynamics_vjp(q, qd, qdd, w, check=c),
}


@pytest.mark.parametrize("check", [True, False])
@pytest.mark.parametrize("batch", [False, True], ids=["one sample", "batch"])
@pytest.mark.parametrize("call", sorted(CALLS))
def test_a_public_derivative_call_reaches_its_kernel_in_few_own_calls(exo, call, batch, check):
    D, *arrays = exo
    if not batch:
        arrays = [np.ascontiguousarray(a[3]) for a in arrays]
    f = CALLS[call]
    first = f(D, *arrays, check)  # resolves its kernels, compiles or loads them
    seen = own_calls(lambda: f(D, *arrays, check))
    assert sum(seen.values()) <= MOST, dict(seen)
    again = f(D, *arrays, check)
    for a, b in zip(first if isinstance(first, tuple) else (first,), again if isinstance(again, tuple) else (again,)):
        np.testing.assert_array_equal(a, b)


def test_the_derivatives_need_no_api_and_take_their_facts_from_the_class():
    """A prepared model built from its class alone, ``exo_bench.api`` never imported, has its derivatives
    (before: a ValueError until ``exo_bench.prepare`` registered the provider), their source from the class:
    newton-euler differentiates its own passes, matrix-paper gets the correct equations."""
    code = """
import sys
import numpy as np
from exo_bench.models.mechanism import presets
from exo_bench.models.newton_euler.prepared import NewtonEuler
from exo_bench.matrix_method.prepared import MatrixPaper
mech = presets.exo5(dim=3)
ne = NewtonEuler(mech)
q = np.linspace(0.1, 0.9, mech.dof)
jq, jqd, M = ne.derivatives.inverse_dynamics(q, q, q)
np.testing.assert_allclose(M, ne.mass_matrix(q), rtol=1e-12, atol=1e-12)
assert "the same equations that newton-euler evaluates" in ne.derivatives.source
assert "CORRECT equations" in MatrixPaper(mech).derivatives.source
assert "exo_bench.api" not in sys.modules, sorted(m for m in sys.modules if m.startswith("exo_bench.api"))
print("ok")
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-3000:]


def test_the_method_table_lists_the_classes_facts():
    """MethodSpec.known_wrong is its class's (one constant), and only newton-euler's derivatives are its own."""
    from exo_bench.api.methods import METHODS

    for name, spec in METHODS.items():
        if spec.extra:
            continue  # an engine of an optional extra: its class may not import
        cls = spec.load()
        assert cls.known_wrong == spec.known_wrong, name
        assert cls.derivatives_are_its_own == (name == "newton-euler"), name


@pytest.mark.parametrize("check", [True, False])
def test_one_sample_has_the_bits_of_its_row_in_a_batch(exo, check):
    D, q, qd, qdd, tau, w = exo
    batch = D.inverse_dynamics(q[:40], qd[:40], qdd[:40], check=check)
    for s in (0, 17, 39):
        for a, b in zip(D.inverse_dynamics(q[s], qd[s], qdd[s], check=check), batch):
            np.testing.assert_array_equal(a, b[s])


def test_the_one_sample_entry_refuses_what_the_edge_refuses(exo):
    """The compiled one-sample entry decides only the common case: a NaN, a negative length, a vertical rod
    and a wrong length go to the exact checks, which name the field, the coordinate or the link; without
    ``check`` the singular state answers (finite) and a wrong layout is refused naming the field."""
    D, q, qd, qdd, tau, w = exo
    x, xd, xdd = (np.ascontiguousarray(a[5]) for a in (q, qd, qdd))
    n = MECH.nlinks
    bad = x.copy()
    bad[2] = np.nan
    with pytest.raises(ValueError, match=r"field 'q' sample 0 coordinate .*expected a finite number"):
        D.inverse_dynamics(bad, xd, xdd)
    bad = xd.copy()
    bad[1] = np.inf
    with pytest.raises(ValueError, match=r"field 'qd' sample 0"):
        D.inverse_dynamics(x, bad, xdd)
    bad = x.copy()
    bad[2 * n + 1] = -0.5
    with pytest.raises(ValueError, match=r"expected a rod length >= 0"):
        D.inverse_dynamics(bad, xd, xdd)
    vertical = x.copy()
    vertical[n + 2] = np.pi / 2
    with pytest.raises(
        SingularConfigurationError, match=r"inverse-dynamics derivatives: .*sample 0: link 3 .*vertical rod"
    ):
        D.inverse_dynamics(vertical, xd, xdd)
    assert all(np.isfinite(a).all() for a in D.inverse_dynamics(vertical, xd, xdd, check=False))
    with pytest.raises(ValueError, match=r"field 'qd': expected shape \(15,\), got \(14,\)"):
        D.inverse_dynamics(x, xd[:14], xdd, check=False)
    strided = np.repeat(x, 2)[::2]
    with pytest.raises(ValueError, match=r"field 'q': expected .*float64.*not C-contiguous"):
        D.inverse_dynamics(strided, xd, xdd, check=False)
    want = D.inverse_dynamics(x, xd, xdd)
    for a, b in zip(D.inverse_dynamics(strided, xd, xdd), want):  # check=True converts it: the same numbers
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match=r"field 'qdd': expected .*float64.*float32"):
        D.inverse_dynamics(x, xd, xdd.astype(np.float32), check=False)


@pytest.mark.filterwarnings("ignore::PendingDeprecationWarning")  # np.matrix's own
def test_a_matrix_never_reaches_a_kernel(exo):
    """``np.matrix`` (whose rows stay 2-D) is converted with ``check=True`` and refused without, naming the field."""
    D, q, qd, qdd, tau, w = exo
    x, xd, xdd = (np.ascontiguousarray(a[:3]) for a in (q, qd, qdd))
    want = D.inverse_dynamics(x, xd, xdd)
    for a, b in zip(D.inverse_dynamics(np.asmatrix(x), xd, xdd), want):
        np.testing.assert_array_equal(np.asarray(a), b)
    with pytest.raises(ValueError, match=r"field 'q': expected .*float64.*not a subclass"):
        D.inverse_dynamics(np.asmatrix(x), xd, xdd, check=False)
    with pytest.raises(ValueError, match=r"field 'w': .*not a subclass"):
        D.inverse_dynamics_vjp(x, xd, xdd, np.asmatrix(xd), check=False)
