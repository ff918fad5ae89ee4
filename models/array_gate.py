"""The one gate for arrays (issue 49): every array a public call hands to a compiled kernel passes here.

A compiled kernel reads and writes its arrays through raw pointers at the offsets the shape it was
given says; numba checks no bound. So what reaches a kernel is **plain** (:func:`is_plain`): a
base-class :class:`numpy.ndarray` (``type(a) is np.ndarray``: not ``np.matrix``, whose ``reshape(-1)``
stays 2-D, nor a masked array, ``memmap``, ``recarray`` or a user's subclass, whose methods may answer
otherwise), native float64, C-contiguous and aligned, of exactly the shape the kernel indexes.

* **Inputs** (:func:`as_input`, :func:`as_states`): with ``check=True`` anything else that numpy can
  read as real numbers (lists, subclasses, other dtypes, strides, offsets) is converted into a fresh
  plain array; what cannot be (strings, complex, masked entries, a wrong shape) is refused with a
  ValueError naming the argument, the expected and the actual form. With ``check=False`` nothing is
  converted (the caller promised plain arrays; converting would hide a copy in a hot loop): anything
  that is not plain is refused the same way. ``check=False`` checks no value, but never skips this.
* **out** (:func:`as_out`): never converted (the caller reads the result from it): an ``out`` that is
  not plain, of the result's exact shape, writable and apart from every input is refused with a
  ValueError naming ``out``, the expected and the actual array, with ``check=True`` and ``check=False``.

The API (stable; other modules and the derivatives' calls use it):

``is_plain(a) -> bool``
``describe(a) -> str``
``as_input(a, name, shape, where, check) -> np.ndarray``   (``shape``: ints, ``None`` for any length)
``as_states(arrays, names, dof, where, check) -> tuple``   (one shape, ``(dof,)`` or ``(samples, dof)``)
``as_out(out, shape, where, inputs=(), names=()) -> np.ndarray``
``apart(out, arrays) -> bool``

``where`` is what the message starts with (the method, or ``"method: call"``). The one-sample fast path
of the public calls (models/prepared.py) decides the common case in compiled code instead and comes
here, through the same checks, only when it answers "not OK"; the messages are this module's.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

ND = np.ndarray
F8 = np.dtype(np.float64)

#: Bounds only (numpy's MAY_SHARE_BOUNDS): O(1), true for every real overlap, partial or with other
#: strides; also true for interleaved views that share no element, which are refused too (a kernel
#: writing ``out`` while it reads an input needs them apart).
_may_overlap = np.may_share_memory


def is_plain(a: Any) -> bool:
    """``a`` is what a compiled kernel may read through a raw pointer: a base-class ndarray of native
    float64, C-contiguous and aligned (its shape is the caller's to check)."""
    if type(a) is not ND or a.dtype != F8:
        return False
    f = a.flags
    return f.c_contiguous and f.aligned


def describe(a: Any) -> str:
    """How ``a`` is, for a message: its type, dtype, shape and what of its layout is not plain."""
    if a is None:
        return "None"
    if not isinstance(a, ND):
        return type(a).__name__
    kind = "" if type(a) is ND else f"{type(a).__module__}.{type(a).__qualname__} "
    dtype = a.dtype.str if a.dtype.byteorder in "<>" and not a.dtype.isnative else str(a.dtype)
    flags = a.flags
    return (
        f"{kind}{dtype} array of shape {a.shape}"
        + ("" if flags.c_contiguous else f", not C-contiguous (strides {a.strides})")
        + ("" if flags.aligned else ", not aligned")
        + ("" if flags.writeable else ", read-only")
    )


def _shape_text(shape: Sequence[int | None]) -> str:
    parts = ["samples" if s is None else str(s) for s in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def _fits(actual: tuple, shape: Sequence[int | None]) -> bool:
    return len(actual) == len(shape) and all(s is None or a == s for a, s in zip(actual, shape))


def apart(out: np.ndarray, arrays: Sequence[Any]) -> bool:
    """``out`` shares no memory with any of ``arrays`` (ndarrays or None; bounds only)."""
    for a in arrays:
        if isinstance(a, ND) and _may_overlap(out, a):
            return False
    return True


def _real(a: Any, name: str, where: str) -> np.ndarray:
    """``a`` as a fresh or plain base-class float64 C-ordered array, or a ValueError naming ``name``."""
    if isinstance(a, (str, bytes, dict)) or a is None or isinstance(a, bool):
        raise ValueError(f"{where}: field '{name}': expected an array of real numbers, got {describe(a)}")
    if isinstance(a, np.ma.MaskedArray):
        if np.ma.is_masked(a):
            at = tuple(int(i) for i in np.argwhere(np.ma.getmaskarray(a))[0])
            raise ValueError(f"{where}: field '{name}': expected numbers, got a masked entry at {at}")
        a = np.ma.getdata(a)
    if isinstance(a, ND) and a.dtype.kind not in "iuf":
        raise ValueError(f"{where}: field '{name}': expected an array of real numbers, got dtype {a.dtype}")
    try:
        raw = np.asarray(a)
        if raw.dtype.kind not in "iuf":
            raise TypeError
        out = np.array(raw, dtype=F8, order="C", subok=False)  # a fresh base-class array, aligned
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{where}: field '{name}': expected an array of real numbers, got {describe(a)}") from None
    return out


def as_input(a: Any, name: str, shape: Sequence[int | None], where: str, check: bool) -> np.ndarray:
    """Input ``name`` of a call as a plain array of ``shape`` (``None``: any length there): ``a`` itself
    if it is plain and of that shape; with ``check`` a fresh plain copy of anything numpy reads as real
    numbers of that shape; a ValueError naming ``name`` otherwise (module docstring)."""
    if is_plain(a) and _fits(a.shape, shape):
        return a
    if not check:
        raise ValueError(
            f"{where}: field '{name}': expected a C-ordered float64 array of shape {_shape_text(shape)} (a "
            "numpy.ndarray, not a subclass; check=False converts nothing, check=True converts any layout and "
            f"dtype), got {describe(a)}"
        )
    b = _real(a, name, where)
    if not _fits(b.shape, shape):
        raise ValueError(
            f"{where}: field '{name}': expected an array of shape {_shape_text(shape)}, got {describe(a)}"
            + ("" if isinstance(a, ND) else f" of shape {b.shape}")
        )
    return b


def as_states(arrays: Sequence[Any], names: Sequence[str], dof: int, where: str, check: bool) -> tuple:
    """State arrays of one shape, ``(dof,)`` or ``(samples, dof)`` (the first decides), each plain or, with
    ``check``, converted (:func:`as_input`); None entries stay None. With ``check=True`` the values are not
    checked here: that is the caller's (finiteness, lengths, the force bound: models/states.py)."""
    first = arrays[0]
    if type(first) is ND and ((nd := first.ndim) == 1 or nd == 2) and first.shape[-1] == dof:  # one frame
        s = first.shape
        for a in arrays:
            if a is not None and not (
                type(a) is ND and a.shape == s and a.dtype == F8 and a.flags.c_contiguous and a.flags.aligned
            ):
                break
        else:
            return tuple(arrays)
    try:
        nd = first.ndim if isinstance(first, ND) else np.ndim(first)
    except ValueError:  # ragged rows
        nd = -1
    shape: tuple[int | None, ...] = (dof,) if nd == 1 else (None, dof)
    out: list[Any] = []
    ref: tuple | None = None
    for a, name in zip(arrays, names):
        if a is None:
            out.append(None)
            continue
        fits = nd in (1, 2) and (check or (is_plain(a) and _fits(a.shape, shape)))
        b = as_input(a, name, shape, where, check) if fits else None
        if b is None or (ref is not None and b.shape != ref):
            raise ValueError(
                f"{where}: field '{name}': expected C-ordered float64 arrays (numpy.ndarray, not a subclass) of one "
                f"shape, ({dof},) or (samples, {dof})"
                + (
                    ""
                    if check
                    else " (check=False checks memory safety only; check=True converts any layout and dtype)"
                )
                + f", got {describe(a)}"
                + ("" if isinstance(a, ND) else f" of shape {np.shape(a) if nd >= 0 else 'ragged'}")
                + ("" if ref is None else f" ({names[0]}: {ref})")
            )
        ref = b.shape if ref is None else ref
        out.append(b)
    return tuple(out)


def as_out(
    out: Any, shape: Sequence[int], where: str, inputs: Sequence[Any] = (), names: Sequence[str] = ()
) -> np.ndarray:
    """``out`` itself if it is a plain (module docstring), writable array of exactly ``shape`` that
    shares no memory with ``inputs`` (named ``names``); a ValueError naming ``out``, the expected and the
    actual array otherwise. Never converted: the caller reads the result from it."""
    shape = tuple(shape)
    if not (is_plain(out) and out.shape == shape and out.flags.writeable):
        raise ValueError(
            f"{where}: field 'out': expected a writable C-ordered float64 array of shape {shape} (a numpy.ndarray, "
            f"not a subclass), got {describe(out)}"
        )
    for name, a in zip(names or [f"input {i}" for i in range(len(inputs))], inputs):
        if isinstance(a, ND) and _may_overlap(out, a):
            raise ValueError(
                f"{where}: field 'out': expected an array that shares no memory with the inputs, got one that "
                f"overlaps '{name}' (the kernels write out while they read {name}: pass a separate array)"
            )
    return out
