"""Conversion of state arrays at the edge: lists, tuples, pandas DataFrames and Series, masked
arrays, any dtype of real numbers, any layout, turned into one C-ordered float64 ``(samples, dof)``
array, or refused with a message naming the field and, where there is one, the sample and the
coordinate. The checks of the values (finite, lengths >= 0, the force bound) are the compiled pass
of models/validation_pass.py, run by :func:`exo_bench.models.states.as_states` on what this returns."""

from __future__ import annotations

from typing import Any

import numpy as np

from exo_bench.models.validation import _is_number


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
