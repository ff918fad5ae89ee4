"""State arrays at the edge: their conversion to C-ordered float64 and the one gate for arrays (issue 49): every array a public call hands to a compiled kernel passes here.

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
of the public calls (models/runtime/prepared.py) decides the common case in compiled code instead and comes
here, through the same checks, only when it answers "not OK"; the messages are this module's.

**Conversion** of state arrays at the edge: lists, tuples, pandas DataFrames and Series, masked
arrays, any dtype of real numbers, any layout, turned into one C-ordered float64 ``(samples, dof)``
array, or refused with a message naming the field and, where there is one, the sample and the
coordinate. The checks of the values (finite, lengths >= 0, the force bound) are the compiled pass
of models/states/validation_pass.py, run by :func:`exo_bench.models.states.states.as_states` on what this returns.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from exo_bench.models.states.validation import _is_number


def _array_problem(arr: Any) -> str:
    """What is wrong with a nested list that numpy cannot turn into a float array: ragged rows,
    or the first entry that is not a number."""
    if isinstance(arr, (list, tuple)):
        rows = [r for r in arr]
        if rows and all(isinstance(r, (list, tuple, np.ndarray)) for r in rows):
            lengths = [len(r) if np.ndim(r) else -1 for r in rows]
            if len(set(lengths)) > 1:
                k = next(i for i, n in enumerate(lengths) if n != lengths[0])
                return (
                    f"ragged rows: expected every row to have the same number of coordinates, got row 0 with "
                    f"{lengths[0]} and row {k} with {lengths[k]}"
                )
            for s_, r in enumerate(rows):
                for c, x in enumerate(r):
                    if not _is_number(x):
                        return f"expected numbers, got {x!r} ({type(x).__name__}) at sample {s_}, column {c}"
        for c, x in enumerate(rows):
            if not isinstance(x, (list, tuple)) and not _is_number(x):
                return f"expected numbers, got {x!r} ({type(x).__name__}) at index {c}"
        if any(isinstance(r, (list, tuple)) for r in rows) and not all(isinstance(r, (list, tuple)) for r in rows):
            return "ragged rows: expected a list of rows (lists of numbers), got a mix of rows and numbers"
        return "expected a list of rows of numbers"
    return f"expected numbers, got {type(arr).__name__}"


def _first_bool(arr) -> tuple[bool, str] | None:
    """The first boolean in a list of rows (or of numbers), with where it is."""
    for s_, r in enumerate(arr):
        if isinstance(r, (list, tuple)):
            if any(type(x) is bool for x in r):
                c = next(c for c, x in enumerate(r) if type(x) is bool)
                return r[c], f"sample {s_}, column {c}"
        elif type(r) is bool:
            return r, f"index {s_}"
    return None


def _where_in(shape: tuple, index: tuple, names: list[str]) -> str:
    """``sample s, coordinate c`` (or ``coordinate c`` of one sample) of an index into states."""
    if len(index) == 2:
        return f"sample {index[0]}, coordinate {names[index[1]] if index[1] < len(names) else index[1]}"
    if len(index) == 1 and len(shape) == 1:
        return f"coordinate {names[index[0]] if index[0] < len(names) else index[0]}"
    return f"index {index}"


def _labelled(arr: Any, label: str, source: str, names: list[str]) -> Any:
    """A pandas DataFrame (or Series) read by its labels, a masked array without masked entries; any
    other input unchanged.

    A DataFrame whose columns are the coordinate names (:func:`coordinate_names`) is reordered to
    them; one whose columns are numbered 0..dof-1 (pandas' default) is read by position; any other
    columns are refused, naming the missing and unexpected ones (a frame read by position after two
    named columns were swapped gave forces off by 222, with no word). A masked entry is refused,
    naming where it is: a masked array's data under its mask is not a state."""
    if isinstance(arr, np.ma.MaskedArray):
        mask = np.ma.getmaskarray(arr)
        if mask.any():
            at = tuple(int(i) for i in np.argwhere(mask)[0])
            raise ValueError(
                f"{source}: field '{label}': expected numbers, got a masked entry at {_where_in(arr.shape, at, names)} "
                "(fill or drop the masked samples first)"
            )
        return np.ma.getdata(arr)
    columns = getattr(arr, "columns", None)
    index = getattr(arr, "index", None) if columns is None and hasattr(arr, "to_numpy") else None
    labels = columns if columns is not None else index
    if labels is None or not hasattr(arr, "to_numpy"):
        return arr
    labels = list(labels)
    if labels == list(range(len(labels))):
        return arr.to_numpy()
    if sorted(map(str, labels)) == sorted(names) and len(set(labels)) == len(labels):
        return (arr[names] if columns is not None else arr[names]).to_numpy()
    missing = [n for n in names if n not in labels]
    unexpected = [c for c in labels if c not in names]
    raise ValueError(
        f"{source}: field '{label}': expected {'columns' if columns is not None else 'an index'} named "
        f"{names[0]}..{names[-1]} (read by name) or numbered 0..{len(names) - 1} (read by position), got "
        + ", ".join(
            part
            for part in (
                f"missing {missing[:5]}" if missing else "",
                f"unexpected {unexpected[:5]}" if unexpected else "",
                "duplicate names" if len(set(labels)) != len(labels) else "",
            )
            if part
        )
    )


def _non_number(arr: Any, names: list[str]) -> str | None:
    """Why a list of states is not numbers (strings, bytes, Decimal, Fraction, None, complex, other
    objects), naming the first entry that is not a real number; None if every entry is one (booleans
    are named by :func:`_first_bool`)."""
    raw = np.asarray(arr)
    if raw.dtype.kind in "iufb":
        return None
    objects = np.asarray(arr, dtype=object)  # the entries as given (numpy made strings of numbers beside a string)
    for at in np.ndindex(objects.shape):
        x = objects[at]
        if not _is_number(x) and type(x) is not bool:
            return f"expected real numbers, got {x!r} ({type(x).__name__}) at {_where_in(objects.shape, at, names)}"
    return None  # Python ints beyond int64 beside floats: numbers, converted below


def converted(arr: Any, label: str, source: str, names: list[str]) -> np.ndarray:
    """``arr`` (field ``label`` of ``source``) as a C-ordered float64 ``(samples, dof)`` array, dof =
    ``len(names)``; a ValueError naming the field (and the sample and coordinate) for what is not a
    state array: strings, dicts, booleans, entries that are not real numbers, ragged rows, dtypes that
    are not real numbers, wrong shapes, DataFrames with other columns, masked entries."""
    if isinstance(arr, (str, bytes, dict)) or arr is True or arr is False:
        raise ValueError(f"{source}: field '{label}': expected numbers, got {type(arr).__name__}")
    if not isinstance(arr, np.ndarray) or isinstance(arr, np.ma.MaskedArray):
        arr = _labelled(arr, label, source, names)
    if isinstance(arr, np.ndarray) and arr.dtype.kind not in "iuf":
        raise ValueError(f"{source}: field '{label}': expected an array of real numbers, got dtype {arr.dtype}")
    try:
        if not isinstance(arr, np.ndarray):  # a list: numbers only (numpy would parse "  1_0.5e0  " as 10.5)
            why = _non_number(arr, names)
            if why is not None:
                raise ValueError(f"{source}: field '{label}': {why}")
        a = np.asarray(arr, dtype=float)
    except (TypeError, ValueError, OverflowError) as e:
        if str(e).startswith(f"{source}: field"):
            raise
        raise ValueError(f"{source}: field '{label}': {_array_problem(arr)}") from None
    if isinstance(arr, (list, tuple)):  # numpy takes true/false as 1.0/0.0: JSON booleans are not numbers
        where = _first_bool(arr)
        if where is not None:
            raise ValueError(f"{source}: field '{label}': expected numbers, got {where[0]!r} (a boolean) at {where[1]}")
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim == 2 and not (a.flags.c_contiguous and a.flags.aligned):
        a = np.array(a, order="C")  # a DataFrame's values, a transpose, an .npz of asfortranarray, an offset
    if a.ndim != 2 or a.shape[1] != len(names):
        raise ValueError(
            f"{source}: field '{label}': expected shape (samples, {len(names)}) in the order "
            f"{names[0]}..{names[-1]}, got {tuple(np.shape(arr))}"
        )
    return a


def real_numbers_problem(arr: Any) -> str:
    """Why ``arr``, of any shape (``f_ext``), is not real numbers ('' if it is): an array of another dtype
    (str, bool, complex, object), a masked entry, or a list entry that numpy would read as a number
    ("1.5", True, Decimal)."""
    if isinstance(arr, np.ma.MaskedArray) and np.ma.is_masked(arr):
        at = tuple(int(i) for i in np.argwhere(np.ma.getmaskarray(arr))[0])
        return f"a masked entry at {at}"
    if isinstance(arr, np.ndarray):
        return "" if arr.dtype.kind in "iuf" else f"dtype {arr.dtype}"
    objects = np.asarray(arr, dtype=object)
    for at in np.ndindex(objects.shape):
        if not _is_number(objects[at]):
            return f"{objects[at]!r} ({type(objects[at]).__name__}) at {at}"
    return ""


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
    checked here: that is the caller's (finiteness, lengths, the force bound: models/states/states.py)."""
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
            f"{where}: field 'out': expected a writable C-ordered float64 array of shape {shape}, got {describe(out)} "
            "(out is a numpy.ndarray itself, not a subclass, and is never converted)"
        )
    for name, a in zip(names or [f"input {i}" for i in range(len(inputs))], inputs):
        if isinstance(a, ND) and _may_overlap(out, a):
            raise ValueError(
                f"{where}: field 'out': expected an array that shares no memory with the inputs, got one that "
                f"overlaps '{name}' (the kernels write out while they read {name}: pass a separate array)"
            )
    return out
