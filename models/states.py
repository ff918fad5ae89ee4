"""State arrays of a mechanism: coordinate and force labels in block order, splitting ``q`` into its
``phi, psi, l`` blocks, and :func:`as_states`, which validates ``q, qd, qdd`` at the edge."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, cast

import numpy as np

if TYPE_CHECKING:
    from exo_bench.models.mechanism import Mechanism

from exo_bench.models import equation_form
from exo_bench.models.validation import MAX_FORCE_SCALE, _is_number, _where, force_scale_log10


def coordinate_names(mech: Mechanism) -> list[str]:
    """Labels in block order: ``phi1..phin, psi1..psin, l1..ln`` (no psi in 2D)."""
    k = range(1, mech.nlinks + 1)
    return [f"{b}{i}" for b in equation_form.blocks(mech.dim) for i in k]


def force_names(mech: Mechanism) -> list[str]:
    """Labels of the generalised forces, same order: ``M_phi.., M_psi.., F..``."""
    k = range(1, mech.nlinks + 1)
    blocks = ["M_phi", "M_psi", "F"] if mech.dim == 3 else ["M_phi", "F"]
    return [f"{b}{i}" for b in blocks for i in k]


def split(mech: Mechanism, q: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Split ``(..., dof)`` into ``phi, psi, l`` blocks of shape ``(..., n)``; psi is None in 2D."""
    n = mech.nlinks
    if mech.dim == 2:
        return q[..., :n], None, q[..., n:]
    return q[..., :n], q[..., n : 2 * n], q[..., 2 * n :]


#: Rows checked at a time for NaN/Inf and negative lengths: the check's own memory stays fixed.
CHECK_ROWS = 65536


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


def is_one_sample(q: Any) -> bool:
    """Whether ``q`` is one sample ``(dof,)``; False for what numpy cannot shape (ragged rows), which
    :func:`as_states` then refuses with its own message."""
    try:
        return np.ndim(q) == 1
    except ValueError:
        return False


def as_states(mech: Mechanism, q: Any, qd: Any = None, qdd: Any = None, source: str = "states"):
    """Validate state arrays at the edge and return them as C-ordered float64 ``(samples, dof)`` arrays.

    Accepts one sample ``(dof,)`` or a batch ``(samples, dof)``. Rejects wrong shapes, ragged
    rows, entries that are not numbers, NaN/Inf, negative rod lengths (each with a message naming
    the array, sample and coordinate) and states whose forces would overflow float64
    (:func:`force_scale_log10` above :data:`MAX_FORCE_SCALE`). C-ordered float64 arrays are not copied (others are: any layout or stride is accepted); the
    checks run :data:`CHECK_ROWS` rows at a time.
    """
    names = coordinate_names(mech)
    out: list[np.ndarray | None] = []
    for label, arr in (("q", q), ("qd", qd), ("qdd", qdd)):
        if arr is None:
            out.append(None)
            continue
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
                raise ValueError(
                    f"{source}: field '{label}': expected numbers, got {where[0]!r} (a boolean) at {where[1]}"
                )
        if a.ndim == 1:
            a = a[None, :]
        if a.ndim == 2 and not a.flags.c_contiguous:
            a = np.ascontiguousarray(a)  # a DataFrame's values, a transpose, an .npz of asfortranarray
        if a.ndim != 2 or a.shape[1] != mech.dof:
            raise ValueError(
                f"{source}: field '{label}': expected shape (samples, {mech.dof}) in the order "
                f"{names[0]}..{names[-1]}, got {tuple(np.shape(arr))}"
            )
        for s0 in range(0, a.shape[0], CHECK_ROWS):
            bad = ~np.isfinite(a[s0 : s0 + CHECK_ROWS])
            if bad.any():
                s, c = map(int, np.argwhere(bad)[0])
                s += s0
                raise ValueError(
                    f"{source}: field '{label}' sample {s} coordinate {names[c]}: "
                    f"expected a finite number, got {a[s, c]}"
                )
        out.append(a)
    shapes = {a.shape[0] for a in out if a is not None}
    if len(shapes) > 1:
        raise ValueError(f"{source}: q, qd and qdd must have the same number of samples, got {sorted(shapes)}")
    n = mech.nlinks
    length = rate = acceleration = 0.0
    first = cast(np.ndarray, out[0])  # q is required
    for s0 in range(0, first.shape[0], CHECK_ROWS):
        l = first[s0 : s0 + CHECK_ROWS, -n:]
        if (l < 0).any():
            s, i = map(int, np.argwhere(l < 0)[0])
            s += s0
            raise ValueError(
                f"{source}: field 'q' sample {s} coordinate l{i + 1} ({_where(i, mech.names[i])}): "
                f"expected a rod length >= 0, got {l[s - s0, i]}"
            )
        if l.size:
            length = max(length, float(l.max()))
        if out[1] is not None and out[1].size:
            rate = max(rate, float(np.abs(out[1][s0 : s0 + CHECK_ROWS]).max()))
        if out[2] is not None and out[2].size:
            acceleration = max(acceleration, float(np.abs(out[2][s0 : s0 + CHECK_ROWS]).max()))
    scale = force_scale_log10(mech, length, rate, acceleration)
    if not scale < math.log10(MAX_FORCE_SCALE):
        big = max(max(ms) for ms in mech.masses)
        raise ValueError(
            f"{source}: the forces would overflow float64: with masses up to {big:.3g} kg, "
            f"rod lengths up to {length:.3g}, rates up to {rate:.3g} and accelerations up to "
            f"{acceleration:.3g} the force bound is 1e{scale:.0f} > {MAX_FORCE_SCALE:.0e} "
            "(models/validation.py force_scale_log10); express the states in other units"
        )
    return tuple(out)
