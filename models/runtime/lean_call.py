"""The lean one-sample call of a compiled kernel: the C wrapper models/runtime/_lean_call.c (built by setup.py,
optional) around a numba ``cfunc`` ``void f(double *params, double *q, double *qd, double *qdd,
double *out, int64 n)`` (inverse dynamics) or ``int64 f(double *params, double *q, double *qd, double
*tau, double *out, int64 n)`` (forward dynamics, answering 0 where it computed the result), bound once
per prepared model and held by its kernel's entries (nothing is rebound). matrix-factored's lean kernel
(:mod:`exo_bench.matrix_method.numba_kernels.lean`), newton-euler's
(:mod:`exo_bench.models.newton_euler.lean`) and their checked forward dynamics of one sample
(``cholesky-forward``: :mod:`exo_bench.matrix_method.numba_kernels.cholesky_forward_c`; ``tree-forward``:
:mod:`exo_bench.models.newton_euler.forward_lean`) are such calls.

The wrapper takes the arguments of ``inverse_dynamics(q, qd, qdd, check, out)`` (or
``forward_dynamics(q, qd, tau, check, out)``); for ``check=False`` it checks in C what memory safety
needs (ndarrays, one dimension of ``dof``, stride 8, float64, ``out`` writable and apart from the
inputs: data pointers and extents compared as integers) and calls the cfunc with the raw pointers,
into ``out`` or, without one, into a result of its own: one of the two it returned last that nothing
refers to any more (no name, view, buffer or weak reference: the caller dropped it, as a loop that
assigns each result to one name does), else a new array (``numpy.empty(dof)``, called from C). Given the
mechanism's validation ``plan``, it takes ``check=True`` too, on plain ndarrays only: the validation
pass of one sample (:func:`exo_bench.models.states.validation_pass.status_address`, the same compiled checks
as ``check=True``'s Python path) runs first, through its C address, and the kernel only where it
answers OK. A forward kernel that answers anything but 0 (a state near a bound of the checks, an answer
that is not finite) declines the call, having written nothing the caller sees (it writes into the
wrapper's scratch memory, copied into ``out`` only when it answers 0). Every call it does not take
goes to ``fallback`` unchanged (:func:`declined`: PreparedModel's Python path then runs and names
the problem).

**The public call itself** (:func:`public_call`): PreparedModel's ``inverse_dynamics`` and
``forward_dynamics`` are defined once, in the base class, as the extension's ``PublicCall``, a method
descriptor around the Python function. A call offers its arguments, as the caller gave them, to the
instance's lean entry (``self._entries.lean`` or ``.forward_lean``, held by the kernel's entries, nothing
rebound) in C, and runs the Python function only where there is none or it declines: a one-sample call
runs no Python frame (about 100 ns of a 0.7 us call on exo5-3d). ``model.inverse_dynamics`` is a bound
method, ``PreparedModel.inverse_dynamics`` the descriptor, carrying the function's name, docstring and
signature (``__wrapped__``). Without the extension it is the plain function.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
import weakref
from typing import Any, TypeVar, cast

import numpy as np

from exo_bench.models.runtime.kernels import NUMBA_BYTES, ONE_SAMPLE, Entries, Kernel


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


#: The interface of models/runtime/_lean_call.c this module calls (its ``VERSION``): an extension built
#: before it (no ``out``-less calls, no forward kernels, no allocation through numpy's C API, no reuse of
#: dropped results, no ``PublicCall``) is not used.
VERSION = 5


def extension() -> Any:
    """The compiled module models/runtime/_lean_call.c, or None where it was not built (no C compiler at
    install) or is of another :data:`VERSION`."""
    try:
        from exo_bench.models.runtime import _lean_call  # type: ignore[attr-defined]  # C, setup.py
    except ImportError:
        return None
    return _lean_call if getattr(_lean_call, "VERSION", None) == VERSION else None


F = TypeVar("F", bound=Callable[..., Any])


def public_call(entry: str) -> Callable[[F], F]:
    """Decorates a public call of PreparedModel whose first arguments are those of a lean entry
    (``(self, a, b, c, check=True, out=None, ...)``): the extension's ``PublicCall`` around it, which
    offers each call to ``self._entries.<entry>`` first (module docstring); the function itself where
    the extension is not built."""

    def wrap(f: F) -> F:
        ext = extension()
        if ext is None:
            return f
        return cast(F, functools.update_wrapper(ext.PublicCall(f, entry), f))

    return wrap


def declined(*args: Any, **kw: Any) -> None:
    """The fallback of a lean call: the call is not one it takes (None: PreparedModel's path goes on)."""
    return None


def c_call(
    address: int | None,
    params: np.ndarray,
    fallback: Any,
    dof: int,
    n: int,
    plan: Any = None,
    forward: bool = False,
    scratch: int = 0,
) -> Any:
    """The compiled wrapper around the cfunc at ``address``, called with the data of :func:`block`
    (``params`` then ``scratch`` doubles of the kernel's scratch, one aligned block) and ``n``:
    a callable ``(q, qd, qdd, check, out)`` (module docstring), taking ``check=True`` where ``plan``
    (:func:`exo_bench.models.states.validation_pass.plan` of the mechanism) is given; ``forward``: the cfunc is a
    forward kernel (answers 0 when done). None where the extension was not built (no C compiler at
    install) or is of another :data:`VERSION`, there is no cfunc (``address`` None: ``NUMBA_DISABLE_JIT``),
    ``params`` is not a C-ordered float64 array, or the extension reads numpy's arrays differently from
    what numpy reports (checked here on probe arrays, before any use)."""
    _lean_call = extension()
    if _lean_call is None:  # not built, or built from an older models/runtime/_lean_call.c
        return None
    f8 = np.dtype(np.float64)
    if address is None or not (params.dtype is f8 and params.flags.c_contiguous):
        return None
    params = block(params, scratch)
    checked: tuple = ()
    if plan is not None:
        from exo_bench.models.states.validation_pass import status_address

        validate = status_address()
        if validate is not None and plan.dtype == np.int64 and plan.flags.c_contiguous and int(plan[0]) == dof:
            checked = (plan, validate, plan.ctypes.data)

    def build(api: Any) -> Any:
        return _lean_call.LeanCall(
            fallback,
            params,
            np.ndarray,
            f8,
            address,
            params.ctypes.data,
            dof,
            n,
            *checked,
            empty=np.empty,
            forward=forward,
            api=api,
        )

    call = build(_numpy_api())  # results allocated through numpy's C API, else by numpy.empty
    ro, held, whole = np.zeros(dof), np.zeros(dof), np.zeros(2 * dof)
    ro.flags.writeable = False
    ref = weakref.ref(held)
    plain = (True, True, False, True, True, None)  # f8, ndarray, no weak reference, owns data, C-ordered, no base
    probes = [
        (np.zeros(dof), (1, dof, 8, True, *plain)),
        (whole[::2], (1, dof, 16, True, True, True, False, False, False, whole)),
        (ro, (1, dof, 8, False, *plain)),
        (np.zeros((2, dof)), (2, 2, 8 * dof, True, *plain)),
        (np.zeros(dof, np.float32), (1, dof, 4, True, False, *plain[1:])),
        (np.zeros(dof, ">f8"), (1, dof, 8, True, False, *plain[1:])),
        (held, (1, dof, 8, True, True, True, True, True, True, None)),
    ]
    if ref() is not held or any(not _same(call.probe(a), want) for a, want in probes):
        return None
    if not _fresh(call.allocate(), dof):
        call = build(None)
    return call if _fresh(call.allocate(), dof) else None


#: The alignment of :func:`block` in bytes: a cache line.
ALIGN = 64


def block(params: np.ndarray, scratch: int = 0) -> np.ndarray:
    """One new float64 block, :data:`ALIGN`-byte aligned: ``params`` (flat) then ``scratch`` zeros, the
    scratch of the kernel that reads ``params`` (the cfunc finds it after its parameters). Made once
    per prepared model, so a lean call allocates nothing per call (numba's ``np.empty`` in the kernel
    cost about 90 ns of a 0.3 us call on exo5-3d, tests/test_lean_scratch.py). The scratch is shared
    by the calls of one model: the wrapper holds the GIL through the kernel, so calls never overlap."""
    size = params.size + int(scratch)
    raw = np.zeros(size + ALIGN // 8)
    start = (-raw.ctypes.data % ALIGN) // 8
    out = raw[start : start + size]
    out[: params.size] = params.reshape(-1)
    return out


def _same(got: tuple, want: tuple) -> bool:
    """A probe's answer is ``want`` (its last entry, the array's base, compared by identity)."""
    return len(got) == len(want) and got[:-1] == want[:-1] and got[-1] is want[-1]


def _fresh(a: Any, dof: int) -> bool:
    """``a`` is a new result as the lean call makes it: a writable C-ordered float64 ndarray of ``dof``
    entries that owns its memory."""
    return (
        type(a) is np.ndarray
        and a.shape == (dof,)
        and a.dtype == np.float64
        and a.dtype.isnative
        and a.flags.c_contiguous
        and a.flags.writeable
        and a.flags.owndata
    )


def _numpy_api() -> Any:
    """numpy's C-API capsule (``_ARRAY_API`` of its multiarray module), through which the wrapper
    allocates results without calling ``numpy.empty`` (entry 94, ``PyArray_NewFromDescr``); None where
    numpy has none."""
    import importlib

    for name in ("numpy._core._multiarray_umath", "numpy.core._multiarray_umath"):
        try:
            capsule = getattr(importlib.import_module(name), "_ARRAY_API", None)
        except ImportError:
            continue
        if capsule is not None and type(capsule).__name__ == "PyCapsule":
            return capsule
    return None
