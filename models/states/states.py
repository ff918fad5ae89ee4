"""State arrays of a mechanism: coordinate and force labels in block order, splitting ``q`` into its
``phi, psi, l`` blocks, and :func:`as_states`, which validates ``q, qd, qdd`` at the edge.

Validation is one compiled pass (models/states/validation_pass.py). C-ordered float64 ndarrays, the arrays
a controller or an ODE right-hand side passes, go straight to it: a few attribute tests, one call of
compiled code, no copy, no name built. Anything else (lists, DataFrames, masked arrays, other dtypes
or layouts) is converted at the edge first (models/states/array_gate.py). Only on a problem does
Python build the message, naming the array, the sample, the coordinate and the link.

**The form of the equations of motion**, eq. (5) (2D) and eq. (17) (3D), defined once (the block order
of the states is the order of its blocks).

Row ``i`` of block ``k`` (``k`` in :func:`blocks`) reads::

    sum_j ( A phi''_j + B psi''_j + Lambda l''_j
          + D phi'_j^2 + E psi'_j^2 + 2 G phi'_j psi'_j + 2 H phi'_j l'_j + 2 K psi'_j l'_j ) + g P_i
    = M_k,i  (k = phi, psi)   or   F_i  (k = l)

with every matrix of that block (``A`` meaning ``A_k`` and so on). :data:`RATES` says which rates
each matrix multiplies and with which factor; :data:`ACCELERATION` which matrix multiplies the
second derivatives of each block (the columns of the mass matrix). Every implementation that
forms, reads or prints the matrices (numeric, symbolic, Lagrange's extraction, the LaTeX export)
takes the order and the factors from here.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from exo_bench.models.states.array_gate import converted
from exo_bench.models.states.validation import MAX_FORCE_SCALE, _where, force_scale_base, force_scale_log10

if TYPE_CHECKING:
    from exo_bench.models.mechanism.mechanism import Mechanism


#: matrix name -> (factor, coordinate blocks whose rates it multiplies). One block: second
#: derivatives of that block; two blocks: the product of their first derivatives.
RATES: dict[str, tuple[float, tuple[str, ...]]] = {
    "A": (1.0, ("phi",)),
    "B": (1.0, ("psi",)),
    "Lambda": (1.0, ("l",)),
    "D": (1.0, ("phi", "phi")),
    "E": (1.0, ("psi", "psi")),
    "G": (2.0, ("phi", "psi")),
    "H": (2.0, ("phi", "l")),
    "K": (2.0, ("psi", "l")),
}

#: The matrices of eq. (5) (2D) and eq. (17) (3D), in the paper's order; ``P`` is the gravity vector.
PLANAR_NAMES = ("A", "Lambda", "D", "H")
SPATIAL_NAMES = ("A", "B", "Lambda", "D", "E", "G", "H", "K")

#: coordinate block -> the matrix multiplying its second derivatives (a column block of M).
ACCELERATION = {"phi": "A", "psi": "B", "l": "Lambda"}


def blocks(dim: int) -> tuple[str, ...]:
    """The coordinate blocks in the order of ``q``: ``phi, l`` in 2D, ``phi, psi, l`` in 3D."""
    if dim not in (2, 3):
        raise ValueError(f"dim: expected 2 or 3, got {dim!r}")
    return ("phi", "psi", "l") if dim == 3 else ("phi", "l")


def matrix_names(dim: int) -> tuple[str, ...]:
    """The matrices of one block of eq. (5) (2D) or eq. (17) (3D), ``P`` excluded."""
    return SPATIAL_NAMES if dim == 3 else PLANAR_NAMES


def coordinate_names(mech: Mechanism) -> list[str]:
    """Labels in block order: ``phi1..phin, psi1..psin, l1..ln`` (no psi in 2D)."""
    k = range(1, mech.nlinks + 1)
    return [f"{b}{i}" for b in blocks(mech.dim) for i in k]


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


#: The old check ran this many rows at a time; the compiled pass needs no scratch memory at all. Kept
#: for the code that imports the name.
CHECK_ROWS = 65536

LABELS = ("q", "qd", "qdd")


class StateCheck:
    """What the check of a mechanism's states needs, computed once per mechanism
    (:func:`state_check`): sizes, the mechanism's part of the force bound
    (:func:`~exo_bench.models.states.validation.force_scale_base`) and the limit; and, resolved on first use
    (importing numba then, not with the mechanism), the compiled pass's entry points and its
    ``plan`` of this mechanism (:func:`exo_bench.models.states.validation_pass.plan`)."""

    __slots__ = ("dof", "nlinks", "base", "lg_g", "limit", "plan", "by_ndim")

    def __init__(self, dof: int, nlinks: int, base: float, lg_g: float, limit: float) -> None:
        self.dof, self.nlinks, self.base, self.lg_g, self.limit = dof, nlinks, base, lg_g, limit
        self.plan: np.ndarray | None = None
        #: ``status`` by the arrays' dimension count (index 1 and 2), once resolved
        self.by_ndim: tuple | None = None

    @classmethod
    def of(cls, mech: Mechanism) -> StateCheck:
        return cls(mech.dof, mech.nlinks, *force_scale_base(mech), math.log10(MAX_FORCE_SCALE))

    def resolve(self) -> tuple:
        """Resolve the compiled pass's entry points and plan (models/states/validation_pass.py), kept from now
        on; returns :attr:`by_ndim`."""
        from exo_bench.models.states.validation_pass import entries, plan

        self.plan = plan(self.dof, self.nlinks, self.base, self.lg_g, self.limit)
        e = entries()
        self.by_ndim = by_ndim = (None, e.status_1d, e.status_2d)
        return by_ndim

    def __reduce__(self):  # a pickled mechanism carries the numbers, never the compiled entries
        return (StateCheck, (self.dof, self.nlinks, self.base, self.lg_g, self.limit))


def state_check(mech: Mechanism) -> StateCheck:
    """The :class:`StateCheck` of ``mech``, computed on its first use and kept with the mechanism,
    as its cached properties are (the mechanism is frozen: the check is derived from its fields)."""
    kept = mech.__dict__.get("_state_check")
    if kept is None:
        kept = mech.__dict__["_state_check"] = StateCheck.of(mech)
    return kept


def validation_plan(mech: Mechanism) -> np.ndarray:
    """The compiled pass's plan of ``mech`` (:attr:`StateCheck.plan`, resolving it on first use): what the
    kernels' one-sample entries validate one sample with (:func:`exo_bench.models.states.validation_pass.one_sample`)."""
    chk = state_check(mech)
    if chk.plan is None:
        chk.resolve()
    assert chk.plan is not None
    return chk.plan


def is_one_sample(q: Any) -> bool:
    """Whether ``q`` is one sample ``(dof,)``; False for what numpy cannot shape (ragged rows), which
    :func:`as_states` then refuses with its own message."""
    try:
        return np.ndim(q) == 1
    except ValueError:
        return False


_ND = np.ndarray
_F8 = np.dtype(np.float64)


def checked_states(mech: Mechanism, q: Any, qd: Any = None, qdd: Any = None, source: str = "states"):
    """:func:`as_states`, except that C-ordered float64 arrays of one shape, ``(dof,)`` or
    ``(samples, dof)``, come back as they are (one sample stays 1-D). Anything else comes back
    converted, as ``(samples, dof)`` arrays."""
    chk = mech.__dict__.get("_state_check") or state_check(mech)
    if type(q) is _ND and q.dtype is _F8 and ((nd := q.ndim) == 1 or nd == 2):  # the fast path: one compiled call
        present, b, c = 0, q, q
        if qd is not None:
            if type(qd) is not _ND or qd.dtype is not _F8 or qd.ndim != nd:
                return _at_the_edge(mech, chk, (q, qd, qdd), source)
            present, b = 1, qd
        if qdd is not None:
            if type(qdd) is not _ND or qdd.dtype is not _F8 or qdd.ndim != nd:
                return _at_the_edge(mech, chk, (q, qd, qdd), source)
            present, c = present | 2, qdd
        code = (chk.by_ndim or chk.resolve())[nd](q, b, c, present, chk.plan)
        if not code:
            return q, qd, qdd
        if code != 1:  # 1: another layout, converted at the edge
            _refuse(mech, chk, code, (q, qd, qdd), source)
    return _at_the_edge(mech, chk, (q, qd, qdd), source)


def as_states(mech: Mechanism, q: Any, qd: Any = None, qdd: Any = None, source: str = "states"):
    """Validate state arrays at the edge and return them as C-ordered float64 ``(samples, dof)`` arrays.

    Accepts one sample ``(dof,)`` or a batch ``(samples, dof)``. Rejects wrong shapes, ragged
    rows, entries that are not numbers, NaN/Inf, negative rod lengths (each with a message naming
    the array, sample and coordinate) and states whose forces would overflow float64
    (:func:`force_scale_log10` above :data:`MAX_FORCE_SCALE`). C-ordered float64 arrays are not
    copied (a sample comes back as a ``(1, dof)`` view); others are: any layout or stride is
    accepted. The values are checked by one compiled pass (models/states/validation_pass.py).
    """
    q, qd, qdd = checked_states(mech, q, qd, qdd, source)
    if q.ndim == 2:
        return q, qd, qdd
    return q[None], None if qd is None else qd[None], None if qdd is None else qdd[None]


def _at_the_edge(mech: Mechanism, chk: StateCheck, arrays: tuple, source: str) -> tuple:
    """Convert each array (models/states/array_gate.py), then check them all with the compiled pass;
    the messages come in the order the arrays are read: an array's non-finite entry is named before
    a later array's wrong form, and both before unequal sample counts and lengths."""
    from exo_bench.models.states.validation_pass import NONFINITE, OK, verdict

    names = coordinate_names(mech)
    out: list[np.ndarray | None] = [None, None, None]
    for k, (label, arr) in enumerate(zip(LABELS, arrays)):
        if arr is None:
            continue
        try:
            out[k] = converted(arr, label, source, names)
        except ValueError:
            if k:
                _refuse(mech, chk, NONFINITE, out, source, only_nonfinite=True)
            raise
    samples = sorted({a.shape[0] for a in out if a is not None})
    if len(samples) > 1:
        _refuse(mech, chk, NONFINITE, out, source, only_nonfinite=True)
        raise ValueError(f"{source}: q, qd and qdd must have the same number of samples, got {samples}")
    code = verdict(chk, out)
    if code != OK:
        _refuse(mech, chk, code, out, source)
    return tuple(out)


def _refuse(mech: Mechanism, chk: StateCheck, code: int, arrays, source: str, only_nonfinite: bool = False) -> None:
    """Raise the ValueError for the problem ``code`` of the pass, naming where it is
    (:func:`~exo_bench.models.states.validation_pass.first_problem`); with ``only_nonfinite``, raise only for
    a non-finite entry (and return otherwise)."""
    from exo_bench.models.states.validation_pass import BOUND, NEGATIVE, NONFINITE, first_problem

    two: list[Any] = [None if a is None else a.reshape(1, -1) if a.ndim == 1 else a for a in arrays]
    if code in (NONFINITE, NEGATIVE):
        problem, k, s, c = first_problem(chk, two)
        names = coordinate_names(mech)
        if problem == NONFINITE:
            raise ValueError(
                f"{source}: field '{LABELS[k]}' sample {s} coordinate {names[c]}: "
                f"expected a finite number, got {two[k][s, c]}"
            )
        if problem == NEGATIVE and not only_nonfinite:
            i = c - (mech.dof - mech.nlinks)
            raise ValueError(
                f"{source}: field 'q' sample {s} coordinate {names[c]} ({_where(i, mech.names[i])}): "
                f"expected a rod length >= 0, got {two[0][s, c]}"
            )
    if code == BOUND and not only_nonfinite:
        q, qd, qdd = two
        l = q[:, -mech.nlinks :]
        length, rate, acceleration = (
            max(0.0, float(np.abs(a).max())) if a is not None and a.size else 0.0 for a in (l, qd, qdd)
        )
        scale = force_scale_log10(mech, length, rate, acceleration)
        big = max(max(ms) for ms in mech.masses)
        raise ValueError(
            f"{source}: the forces would overflow float64: with masses up to {big:.3g} kg, "
            f"rod lengths up to {length:.3g}, rates up to {rate:.3g} and accelerations up to "
            f"{acceleration:.3g} the force bound is 1e{scale:.0f} > {MAX_FORCE_SCALE:.0e} "
            "(models/states/validation.py force_scale_log10); express the states in other units"
        )
    if not only_nonfinite:  # a verdict without a place: the pass and its locate disagree
        raise AssertionError(f"{source}: the compiled check answered {code} and found no such problem")
