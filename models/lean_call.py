"""The lean one-sample call of a compiled kernel: the C wrapper models/_lean_call.c (built by setup.py,
optional) around a numba ``cfunc`` ``void f(double *params, double *q, double *qd, double *qdd,
double *out, int64 n)``, bound once per prepared model and held by its kernel's entries (nothing is
rebound). matrix-factored's lean kernel (:mod:`exo_bench.matrix_method.numba_kernels.lean`) and
newton-euler's (:mod:`exo_bench.models.newton_euler.lean`) are such calls.

The wrapper takes the arguments of ``inverse_dynamics(q, qd, qdd, check, out)``; for ``check=False``
with an ``out`` it checks in C what memory safety needs (ndarrays, one dimension of ``dof``, stride 8,
float64, ``out`` writable and apart from the inputs: data pointers and extents compared as integers)
and calls the cfunc with the raw pointers. Given the mechanism's validation ``plan``, it takes
``check=True`` too, on plain ndarrays only: the validation pass of one sample
(:func:`exo_bench.models.validation_pass.status_address`, the same compiled checks as ``check=True``'s
Python path) runs first, through its C address, and the kernel only where it answers OK. Every other
call goes to ``fallback`` unchanged, having written nothing (PreparedModel then names the problem).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from exo_bench.models.kernels import NUMBA_BYTES, ONE_SAMPLE, Entries, Kernel


def lean_kernel(cost: str, compile_seconds: float, load: Callable[[Any], Entries], speed: float = 1.0) -> Kernel:
    """The kernel object of a lean call: inverse dynamics of one sample in the calling thread, option
    ``numba``, its entry ``lean`` bound by ``load`` (which calls :func:`c_call`)."""
    return Kernel(
        "lean",
        "numba",
        ("inverse_dynamics",),
        (ONE_SAMPLE,),
        "one thread: the calling one",
        cost,
        speed=speed,
        compile_seconds=compile_seconds,
        runtime_bytes=NUMBA_BYTES,
        load=load,
    )


def c_call(address: int | None, params: np.ndarray, fallback: Any, dof: int, n: int, plan: Any = None) -> Any:
    """The compiled wrapper around the cfunc at ``address``, called with ``params``'s data and ``n``:
    a callable ``(q, qd, qdd, check, out)`` (module docstring), taking ``check=True`` where ``plan``
    (:func:`exo_bench.models.validation_pass.plan` of the mechanism) is given; None where the extension was not built
    (no C compiler at install), there is no cfunc (``address`` None: ``NUMBA_DISABLE_JIT``), ``params`` is
    not a C-ordered float64 array, or the extension reads
    numpy's arrays differently from what numpy reports (checked here on probe arrays, before any use)."""
    try:
        from exo_bench.models import _lean_call  # type: ignore[attr-defined]  # C, setup.py
    except ImportError:
        return None
    f8 = np.dtype(np.float64)
    if address is None or not (params.dtype is f8 and params.flags.c_contiguous):
        return None
    checked: tuple = ()
    if plan is not None:
        from exo_bench.models.validation_pass import status_address

        validate = status_address()
        if validate is not None and plan.dtype == np.int64 and plan.flags.c_contiguous and int(plan[0]) == dof:
            checked = (plan, validate, plan.ctypes.data)
    call = _lean_call.LeanCall(fallback, params, np.ndarray, f8, address, params.ctypes.data, dof, n, *checked)
    ro = np.zeros(dof)
    ro.flags.writeable = False
    probes = [
        (np.zeros(dof), (1, dof, 8, True, True, True)),
        (np.zeros(2 * dof)[::2], (1, dof, 16, True, True, True)),
        (ro, (1, dof, 8, False, True, True)),
        (np.zeros((2, dof)), (2, 2, 8 * dof, True, True, True)),
        (np.zeros(dof, np.float32), (1, dof, 4, True, False, True)),
        (np.zeros(dof, ">f8"), (1, dof, 8, True, False, True)),
    ]
    if any(call.probe(a) != want for a, want in probes):
        return None
    return call
