"""One way through each public call (issue 47): from the public call to its kernel, a call runs at most
:data:`LIMIT` of the project's own Python functions, counted with ``sys.setprofile`` (a count, not a
time: the same on any machine). exo5-3d, matrix-factored and newton-euler, one sample and a batch,
checked and not: inverse dynamics, forward dynamics, the mass matrix (bias forces beside them).

Counted: every ``call`` event of a Python frame whose file lies in a folder of the package (generators'
resumptions included; numba's and numpy's frames are not the project's) until the first call of a
compiled kernel (numba shows a profiler a call of its dispatcher as a frame of the kernel's Python
function: that frame ends the count; a one-sample entry point shows none, and the whole call is
counted). Before issue 47, a checked batch of inverse dynamics ran 15 of them, forward dynamics 30, the
mass matrix 21 (the issue's table); the counter itself is checked to see them
(:func:`test_the_counter_sees_the_projects_frames`)."""

from __future__ import annotations

import gc
import inspect
import sys
from pathlib import Path

import numpy as np
import pytest

import exo_bench
import exo_bench.bench
import exo_bench.lagrange
import exo_bench.matrix_method
import exo_bench.models
from exo_bench import prepare
from exo_bench.models.motion import smooth_random_motion
from exo_bench.models.newton_euler import passes
from exo_bench.models.presets import exo5

#: The most of the project's functions one public call may run (issue 47's goal).
LIMIT = 8
FOLDERS = tuple(
    str(f) + "/"
    for m in (exo_bench, exo_bench.models, exo_bench.matrix_method, exo_bench.lagrange, exo_bench.bench)
    for p in m.__path__
    for f in {Path(p), Path(p).resolve()}
)
METHODS = ("matrix-factored", "newton-euler")
#: Modules whose functions are kernels written in numpy (newton-euler's analytic mass matrix, O(n^2)).
NUMPY_KERNELS = (passes,)


def _kernels() -> set:
    """The ids of the code objects of every numba dispatcher made so far (the kernels' Python functions;
    ids: a code object's hash may change as the interpreter specialises it) and of the functions of the
    numpy kernel modules (:data:`NUMPY_KERNELS`)."""
    from numba.core.dispatcher import Dispatcher

    codes = {id(d.py_func.__code__) for d in gc.get_objects() if isinstance(d, Dispatcher)}
    for module in NUMPY_KERNELS:
        codes |= {id(f.__code__) for f in vars(module).values() if inspect.isfunction(f)}
    return codes


def own_calls(call) -> list[str]:
    """The project's Python functions entered while ``call()`` runs, in order (``file:function``), up to
    the first compiled kernel (named last, with ``kernel`` before it)."""
    seen: list[str] = []
    kernels = _kernels()
    done = [False]

    def profile(frame, event, arg):
        if event == "call" and not done[0] and frame.f_code.co_filename.startswith(FOLDERS):
            if id(frame.f_code) in kernels:
                done[0] = True
                seen.append(f"kernel {frame.f_code.co_name}")
                return
            seen.append(f"{Path(frame.f_code.co_filename).name}:{frame.f_code.co_name}")

    sys.setprofile(profile)
    try:
        call()
    finally:
        sys.setprofile(None)
    return seen


@pytest.fixture(scope="module", params=METHODS)
def case(request):
    mech = exo5(3)
    model = prepare(mech, request.param)
    mo = smooth_random_motion(mech, np.linspace(0.0, 1.0, 1000), seed=4)
    q, qd, qdd = (np.ascontiguousarray(a) for a in (mo.q, mo.qd, mo.qdd))
    tau = model.inverse_dynamics(q, qd, qdd)
    return model, (q, qd, qdd, tau)


def _calls(model, q, qd, qdd, tau):
    one = [np.ascontiguousarray(a[0]) for a in (q, qd, qdd, tau)]
    out = np.empty(model.dof)
    calls = {}
    for shape, (a, b, c, t) in (("one sample", one), ("batch", (q, qd, qdd, tau))):
        for check in (True, False):
            calls[f"inverse_dynamics, {shape}, check={check}"] = lambda a=a, b=b, c=c, k=check: model.inverse_dynamics(
                a, b, c, check=k
            )
            calls[f"forward_dynamics, {shape}, check={check}"] = lambda a=a, b=b, t=t, k=check: model.forward_dynamics(
                a, b, t, check=k
            )
            calls[f"mass_matrix, {shape}, check={check}"] = lambda a=a, k=check: model.mass_matrix(a, check=k)
            calls[f"bias_forces, {shape}, check={check}"] = lambda a=a, b=b, k=check: model.bias_forces(a, b, check=k)
    calls["inverse_dynamics, one sample, out="] = lambda: model.inverse_dynamics(*one[:3], check=False, out=out)
    return calls


def test_each_public_call_reaches_its_kernel_in_few_own_functions(case):
    model, states = case
    over = {}
    for what, call in _calls(model, *states).items():
        call()  # first use: resolves what is resolved once per model
        seen = [s for s in own_calls(call) if not s.startswith("kernel ")]
        if len(seen) > LIMIT:
            over[what] = seen
    assert not over, "\n".join(f"{model.method}: {w}: {len(s)} own calls: {s}" for w, s in over.items())


def test_the_counter_sees_the_projects_frames(case):
    """The oracle can fail: the checked path of a batch runs the project's functions, and they are seen."""
    model, (q, qd, qdd, tau) = case
    seen = own_calls(lambda: model.inverse_dynamics(q.tolist(), qd, qdd))
    assert any(s.startswith("prepared.py:") for s in seen) and any(s.startswith("states.py:") for s in seen), seen
    assert len(own_calls(lambda: model.mechanism.dof)) >= 0
