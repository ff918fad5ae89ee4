"""What ``check=False`` still checks: memory safety, never values (:func:`unchecked_states`), and the
``out`` array of a call."""

from __future__ import annotations

import numpy as np


#: Bounds only (numpy's MAY_SHARE_BOUNDS): O(1), and true for every real overlap, partial or with
#: other strides; it may also be true for interleaved views that share no element, which are refused
#: too (a kernel writing ``out`` while it reads an input needs them apart).
_may_overlap = np.may_share_memory


def apart(out: np.ndarray, arrays: tuple) -> bool:
    """Whether ``out`` shares no memory with any of ``arrays`` (ndarrays; bounds only, as
    :data:`_may_overlap`): a kernel may write ``out`` while it reads them. One bounds test per array,
    no generator (about 0.1 us each)."""
    for a in arrays:
        if _may_overlap(out, a):
            return False
    return True


def check_out(out, shape: tuple, method: str = "", inputs: tuple = (), names: tuple = ("q", "qd", "qdd")) -> None:
    """``out`` of :meth:`~exo_bench.models.runtime.prepared.PreparedModel.inverse_dynamics`: a writable C-ordered
    float64 array of ``shape`` that shares no memory with the ``inputs`` (named ``names``): the kernels
    write ``out`` while they read them, so an ``out`` that overlaps one, even partly, gives garbage.
    Checked with ``check=False`` too: it is memory safety, not a value."""
    where = f"{method + ': ' if method else ''}field 'out'"
    for name, a in zip(names, inputs):
        if isinstance(out, np.ndarray) and isinstance(a, np.ndarray) and _may_overlap(out, a):
            raise ValueError(
                f"{where}: expected an array that shares no memory with the inputs, got one that overlaps "
                f"'{name}' (the kernels write out while they read {name}: pass a separate array)"
            )
    if not (
        isinstance(out, np.ndarray)
        and out.dtype == np.float64
        and out.shape == tuple(shape)
        and out.flags.c_contiguous
        and out.flags.writeable
    ):
        got = (
            f"{type(out).__name__}"
            if not isinstance(out, np.ndarray)
            else f"{out.dtype} array of shape {out.shape}"
            + ("" if out.flags.c_contiguous else ", not C-ordered")
            + ("" if out.flags.writeable else ", read-only")
        )
        raise ValueError(f"{where}: expected a writable C-ordered float64 array of shape {tuple(shape)}, got {got}")


_F8 = np.dtype(np.float64)


def _describe(a) -> str:
    if not isinstance(a, np.ndarray):
        return "None" if a is None else type(a).__name__
    return (
        f"{a.dtype.str if a.dtype.byteorder == '>' else a.dtype} array of shape {a.shape}"
        + ("" if a.flags.c_contiguous else ", not C-ordered")
        + ("" if a.flags.writeable else ", read-only")
    )


def unchecked_states(method: str, dof: int, arrays: tuple, out=None) -> None:
    """What ``check=False`` still checks: memory safety, never values.

    The kernels read ``samples * dof`` float64 numbers from each state array and write as many
    into ``out``, through raw pointers (numba does not check bounds). So every array must be a
    C-ordered float64 ndarray of one shape, ``(dof,)`` or ``(samples, dof)``, and ``out`` (if given)
    a writable one of that shape. One comparison per property; a ValueError naming the field,
    the expected and the actual array otherwise (a Fortran-ordered batch from a DataFrame would
    otherwise be read in the wrong order, an ``out`` too small written past its end).
    """
    q = arrays[0]
    try:  # straight-line: about 0.15 us on the quiet 2-core machine
        s = q.shape
        ok = len(s) < 3 and s[-1] == dof and q.dtype is _F8 and q.flags.c_contiguous
        for a in arrays[1:]:
            ok = ok and a.shape == s and a.dtype is _F8 and a.flags.c_contiguous
        if ok and out is not None:
            ok = out.shape == s and out.dtype is _F8 and out.flags.c_contiguous and out.flags.writeable
            ok = ok and apart(out, arrays)
    except (AttributeError, IndexError):
        ok = False
    if ok:
        return
    names = ("q", "qd", "qdd")[: len(arrays)]
    expected = (
        f"C-ordered float64 arrays of one shape, (dof,) or (samples, dof) with dof = {dof} "
        "(check=False checks memory safety only; check=True converts any layout and dtype)"
    )
    for name, a in zip(names, arrays):
        good = (
            isinstance(a, np.ndarray)
            and a.dtype == _F8
            and a.flags.c_contiguous
            and a.ndim in (1, 2)
            and a.shape[-1:] == (dof,)
            and a.shape == getattr(q, "shape", None)
        )
        if not good:
            raise ValueError(
                f"{method}: field '{name}': expected {expected}, got {_describe(a)}"
                + ("" if name == "q" or not isinstance(q, np.ndarray) else f" (q: {q.shape})")
            )
    if out is not None:
        check_out(out, q.shape, method, arrays, names)
    # here: safe after all (a float64 dtype object that is not numpy's own, as some libraries make)


def require_rates(method: str, *rates) -> None:
    """``qd`` (and ``qdd``) are required where the call needs them: None is not "zero"."""
    for name, a in zip(("qd", "qdd"), rates):
        if a is None:
            raise ValueError(
                f"{method}: field '{name}': expected an array of shape (dof,) or (samples, dof), "
                "got None (pass zeros for a state at rest)"
            )


def unchecked_forward(method: str, dof: int, q, qd, tau, out) -> None:
    """:func:`unchecked_states` for forward dynamics (its third array is ``tau``)."""
    try:
        unchecked_states(method, dof, (q, qd, tau), out)
    except ValueError as e:
        raise ValueError(str(e).replace("qdd", "tau")) from None
