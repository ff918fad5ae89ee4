"""The compiled generalised forces of ``f_ext``, ``Q(q, f_ext)``, and the calls' fast path.

One numba kernel, :func:`kernel` (models/external_forces_kernel.py), serves the generalised forces themselves
(:func:`generalized_forces_compiled`) and inverse and forward dynamics with ``f_ext``
(:mod:`exo_bench.models.external_forces`): ``dest = tau - Q``, ``tau + Q`` or ``Q``, over flat
C-ordered float64 arrays of any number of samples, with an optional finiteness check of the forces
in the same pass. It holds the arithmetic of :func:`exo_bench.models.external_forces.generalized_forces`
(the same leaves-first sums, the same rod projections as :mod:`exo_bench.models.rod_elements`), so its
numbers are the numpy ones to the last bit.

A prepared model binds what is fixed once (:func:`bound`: the mechanism's parent indices, signs and
middle fractions as one parameter array, and whether the model's ``Q`` is this one: the engines
supply their own), so a call rebuilds nothing: one sample costs the call without ``f_ext``, a few
array checks and one compiled call (bench/test_external_forces.py times it).

**Memory safety.** The kernel reads and writes nothing outside its arrays whatever it is given: it
compares every array's size with what the parameters and the sample count imply and answers
:data:`BAD_SIZE` without touching anything when they differ. Its status is otherwise :data:`DONE`,
or the flat index of the first force that is not finite (``check``: nothing written), which the
caller names (:func:`exo_bench.models.external_forces.check_f_ext`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np

from exo_bench.models.array_gate import is_plain
from exo_bench.models.mechanism import Mechanism

#: The kernel's status: done, or the arrays' sizes disagree with the parameters (nothing touched).
DONE, BAD_SIZE = -1, -2
#: What the kernel writes into ``dest``: ``tau - Q`` (inverse dynamics), ``tau + Q`` (forward), ``Q``.
MINUS, PLUS, ONLY = -1, 1, 0

F8 = np.dtype(np.float64)


def parameters(mech: Mechanism) -> np.ndarray:
    """The kernel's parameter array: ``[dim, parent..., sign..., n...]`` (parents as floats, -1 for a root)."""
    return np.concatenate(([float(mech.dim)], np.asarray(mech.parent, float), mech.sign_array, mech.n))


@cache
def kernel() -> Callable[..., int]:
    """The compiled kernel ``(params, q, f, tau, dest, mode, check) -> status`` (module text):
    :func:`exo_bench.models.external_forces_kernel.apply`'s compiled entry point for flat C-ordered
    float64 arrays, an int64 ``mode`` and a boolean ``check``, loaded from numba's on-disk cache or
    compiled on the first call in a process. ``q``, ``tau``, ``dest``: ``(samples * dof,)``; ``f``:
    ``(samples * links * 3 * dim,)``; ``mode``: :data:`MINUS`, :data:`PLUS` or :data:`ONLY` (``tau``
    unread). ``dest`` may be ``tau``; any other overlap with the inputs is the caller's to avoid.

    The entry point types nothing (no dispatch: a call costs the unboxing and the pass), so its
    callers pass exactly those types (:func:`flat`, ``np.empty``); under ``NUMBA_DISABLE_JIT`` it is
    the Python function."""
    from exo_bench.models.numba_runtime import ensure, jit_disabled

    ensure()  # before the kernel is defined: numba's cache locators
    from exo_bench.models.external_forces_kernel import apply

    if jit_disabled():
        return apply
    from numba import types

    flat_f8 = types.Array(types.float64, 1, "C")
    return apply.compile((flat_f8, flat_f8, flat_f8, flat_f8, flat_f8, types.int64, types.boolean))


def flat(a: Any) -> np.ndarray:
    """``a`` as a flat plain float64 array (:func:`exo_bench.models.array_gate.is_plain`: a view where it
    is one already, else a fresh base-class copy)."""
    if not is_plain(a):
        a = np.array(a, dtype=F8, order="C", subok=False)
    return a.reshape(-1)


def generalized_forces_compiled(
    mech: Mechanism, q: np.ndarray, f: np.ndarray, params: np.ndarray | None = None
) -> np.ndarray:
    """:func:`exo_bench.models.external_forces.generalized_forces` by the compiled kernel (float64 ``q (S,
    dof)``, ``f (S, links, 3, dim)``): ``(S, dof)``."""
    q2 = np.ascontiguousarray(q, dtype=float)
    out = np.empty(q2.shape)
    p = parameters(mech) if params is None else params  # a prepared model passes its own (:func:`bound`)
    status = kernel()(p, q2.reshape(-1), flat(f), out.reshape(-1), out.reshape(-1), ONLY, False)
    if status != DONE or out.shape[-1:] != (mech.dof,):
        raise ValueError(
            f"f_ext: expected q of shape (samples, {mech.dof}) and forces of shape (samples, {mech.nlinks}, 3, "
            f"{mech.dim}), got {q2.shape} and {np.shape(f)}"
        )
    return out


@dataclass(frozen=True)
class Bound:
    """What a prepared model's calls with ``f_ext`` need, bound once (:func:`bound`)."""

    params: np.ndarray
    apply: Callable[..., int] | None  # the kernel; None: the model has its own Q (an engine)
    forces: tuple[int, int, int]  # one sample's f_ext shape, (links, 3, dim)
    dof: int


def bound(model: Any) -> Bound:
    """The :class:`Bound` of a prepared model, made on its first call with ``f_ext`` and kept on it."""
    b = model.__dict__.get("_f_ext_bound")
    if b is None:
        mech = model.mechanism
        # the model's Q is PreparedModel's default (the first class in its lineage to define one; not
        # imported here: prepared imports this module's callers), not an engine's override
        cls = type(model)
        first = next(c for c in reversed(cls.__mro__) if "_external_forces" in vars(c))
        native = cls._external_forces is vars(first)["_external_forces"]
        b = Bound(parameters(mech), kernel() if native else None, (mech.nlinks, 3, mech.dim), mech.dof)
        model.__dict__["_f_ext_bound"] = b
    return b
