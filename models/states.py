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
        if rows and all(isinstance(r, (list, tuple)) for r in rows):
            lengths = [len(r) for r in rows]
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
        if isinstance(arr, np.ndarray) and arr.dtype.kind not in "iuf":
            raise ValueError(f"{source}: field '{label}': expected an array of real numbers, got dtype {arr.dtype}")
        try:
            a = np.asarray(arr, dtype=float)
        except (TypeError, ValueError, OverflowError):
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
