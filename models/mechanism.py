"""The mechanism as plain data: a tree of telescopic rods carrying point masses.

A :class:`Mechanism` is a frozen dataclass in the style of Featherstone's
``model.parent``: link ``i`` hangs from link ``parent[i]`` (``-1`` is the fixed
support point O). Every algorithm in the suite is a free function of the form
``f(mechanism, q, qd, qdd)``.

Generalised coordinates are in block order ``q = [phi_1..phi_n, psi_1..psi_n,
l_1..l_n]`` (no ``psi`` block in 2D); see :func:`coordinate_names`.

Geometry (paper, sections 1-3): link ``i`` starts at the end point of its
parent and points along ``sign[i] * u_i``, where ``u_i`` is the unit vector of
its absolute angles, ``(cos phi, sin phi)`` in 2D and
``(cos psi cos phi, cos psi sin phi, sin psi)`` in 3D (eq. 7). It carries
``masses[i] = (m_i0, m_i1, m_i2)`` at fractions ``(0, n[i], 1)`` of its current
length ``l_i``. ``sign = -1`` is the paper's "lower sign" of eq. (4): the rod is
measured the other way after a branch point (the swing leg hangs down from the
hip while its angle is measured like the stance leg's).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

_LINK_KEYS = {"parent", "sign", "masses", "n"}
_LINK_OPTIONAL = {"name"}
_TOP_KEYS = {"dim", "g", "links"}
_TOP_OPTIONAL = {"name"}


def _where(i: int, name: str | None) -> str:
    return f"link {i + 1}" + (f" ({name!r})" if name else "")


class DuplicateKey(ValueError):
    pass


def unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """``object_pairs_hook`` of every JSON the suite reads: a key given twice in one object is an
    error (``json`` would keep the last one silently)."""
    out = {}
    for k, v in pairs:
        if k in out:
            raise DuplicateKey(f"duplicate key {k!r} in one object (JSON readers disagree on which one counts)")
        out[k] = v
    return out


def loads(text: str) -> Any:
    """``json.loads`` refusing duplicate keys (:func:`unique_keys`)."""
    return json.loads(text, object_pairs_hook=unique_keys)



def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _finite(x: Any) -> bool:
    """A number that is a finite float64 (an integer too large for a float is not)."""
    try:
        return math.isfinite(float(x))
    except (OverflowError, TypeError, ValueError):
        return False


@dataclass(frozen=True)
class Mechanism:
    """A tree of ``n`` telescopic links with three point masses each.

    Fields are tuples so that the mechanism is hashable: models built from it
    (URDF, Pinocchio model, lambdified functions) are cached per mechanism.
    Links are numbered from 0 in code and from 1 in every message and report,
    as in the paper.
    """

    dim: int
    g: float
    parent: tuple[int, ...]
    sign: tuple[int, ...]
    masses: tuple[tuple[float, float, float], ...]
    n: tuple[float, ...]
    names: tuple[str, ...] = ()
    name: str = "mechanism"

    def __post_init__(self) -> None:
        # Normalise containers (lists from callers become tuples) and validate once.
        object.__setattr__(self, "parent", tuple(self.parent))
        object.__setattr__(self, "sign", tuple(self.sign))
        object.__setattr__(self, "masses", tuple(tuple(m) for m in self.masses))
        object.__setattr__(self, "n", tuple(self.n))
        names = tuple(self.names) if self.names else tuple(f"link{i + 1}" for i in range(len(self.parent)))
        object.__setattr__(self, "names", names)
        _validate(self)
        # Store plain Python numbers (numpy scalars would leak into JSON and hashes).
        object.__setattr__(self, "parent", tuple(int(p) for p in self.parent))
        object.__setattr__(self, "sign", tuple(int(s) for s in self.sign))
        object.__setattr__(self, "masses", tuple(tuple(float(x) for x in m) for m in self.masses))
        object.__setattr__(self, "n", tuple(float(x) for x in self.n))
        object.__setattr__(self, "g", float(self.g) + 0.0)  # -0.0 -> 0.0: one mechanism, one hash
        object.__setattr__(self, "dim", int(self.dim))
        object.__setattr__(self, "_hash", hash((self.dim, self.g, self.parent, self.sign, self.masses, self.n,
                                                self.names, self.name)))

    def __hash__(self) -> int:  # cached: models, URDFs and derivations are looked up by mechanism
        return self._hash

    # ----------------------------------------------------------------- sizes
    @property
    def nlinks(self) -> int:
        return len(self.parent)

    @property
    def dof(self) -> int:
        """Number of generalised coordinates: 2n in 2D, 3n in 3D."""
        return self.dim * self.nlinks

    # ------------------------------------------------------ numpy views
    @cached_property
    def mass_array(self) -> np.ndarray:
        """``(n, 3)`` array of ``[m_i0, m_i1, m_i2]``."""
        return np.array(self.masses, dtype=float)

    @cached_property
    def fractions(self) -> np.ndarray:
        """``(n, 3)`` array of ``[n_i0, n_i1, n_i2] = [0, n_i, 1]``."""
        f = np.zeros((self.nlinks, 3))
        f[:, 1] = self.n
        f[:, 2] = 1.0
        return f

    @cached_property
    def sign_array(self) -> np.ndarray:
        return np.array(self.sign, dtype=float)

    @property
    def total_mass(self) -> float:
        return float(self.mass_array.sum())

    # ------------------------------------------------------ tree structure
    @cached_property
    def children(self) -> tuple[tuple[int, ...], ...]:
        kids: list[list[int]] = [[] for _ in range(self.nlinks)]
        for i, p in enumerate(self.parent):
            if p >= 0:
                kids[p].append(i)
        return tuple(tuple(k) for k in kids)

    @cached_property
    def ancestors(self) -> tuple[tuple[int, ...], ...]:
        """Proper ancestors of each link, nearest first."""
        out = []
        for i in range(self.nlinks):
            chain, p = [], self.parent[i]
            while p >= 0:
                chain.append(p)
                p = self.parent[p]
            out.append(tuple(chain))
        return tuple(out)

    @cached_property
    def ancestor_or_self(self) -> np.ndarray:
        """Boolean ``(n, n)``: ``[i, j]`` is true when link i is j itself or one of j's ancestors."""
        a = np.eye(self.nlinks, dtype=bool)
        for j, anc in enumerate(self.ancestors):
            for i in anc:
                a[i, j] = True
        return a

    def is_chain(self) -> bool:
        """True for a serial chain ``parent = (-1, 0, 1, ..., n-2)``."""
        return self.parent == tuple(range(-1, self.nlinks - 1))

    # ------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        links = []
        for i in range(self.nlinks):
            links.append(
                {"name": self.names[i], "parent": self.parent[i], "sign": self.sign[i],
                 "masses": list(self.masses[i]), "n": self.n[i]}
            )
        return {"name": self.name, "dim": self.dim, "g": self.g, "links": links}

    def to_json(self, indent: int | None = 1) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_dict(cls, data: Any, source: str = "mechanism") -> "Mechanism":
        """Build from the JSON format, validating every field with a message that
        names the link, the field, and the expected and actual values."""
        if not isinstance(data, dict):
            raise ValueError(f"{source}: expected a JSON object with keys {sorted(_TOP_KEYS)}, got {type(data).__name__}")
        missing = _TOP_KEYS - data.keys()
        if missing:
            raise ValueError(f"{source}: missing key(s) {sorted(missing)}: expected an object with keys {sorted(_TOP_KEYS)}")
        extra = data.keys() - _TOP_KEYS - _TOP_OPTIONAL
        if extra:
            raise ValueError(f"{source}: unknown key(s) {sorted(extra)}: expected only {sorted(_TOP_KEYS | _TOP_OPTIONAL)}")
        dim, g, links = data["dim"], data["g"], data["links"]
        if not isinstance(dim, int) or isinstance(dim, bool) or dim not in (2, 3):
            raise ValueError(f"{source}: field 'dim': expected 2 or 3, got {dim!r}")
        if not _is_number(g) or not _finite(g):
            raise ValueError(f"{source}: field 'g': expected a finite number, got {g!r}")
        if g < 0:
            raise ValueError(f"{source}: field 'g': {_NEGATIVE_G}, got {g!r}")
        if not isinstance(links, list) or not links:
            raise ValueError(f"{source}: field 'links': expected a non-empty list of links, got {links!r}")
        parent, sign, masses, frac, names = [], [], [], [], []
        for i, link in enumerate(links):
            where = f"{source}: link {i + 1}"
            if not isinstance(link, dict):
                raise ValueError(f"{where}: expected an object with keys {sorted(_LINK_KEYS)}, got {link!r}")
            nm = link.get("name")
            if nm is not None and not isinstance(nm, str):
                raise ValueError(f"{where}: field 'name': expected a string, got {nm!r}")
            where = f"{source}: {_where(i, nm)}"
            missing = _LINK_KEYS - link.keys()
            if missing:
                raise ValueError(f"{where}: missing field(s) {sorted(missing)}: expected keys {sorted(_LINK_KEYS)}")
            extra = link.keys() - _LINK_KEYS - _LINK_OPTIONAL
            if extra:
                raise ValueError(f"{where}: unknown field(s) {sorted(extra)}: expected only {sorted(_LINK_KEYS | _LINK_OPTIONAL)}")
            p, s, m, f = link["parent"], link["sign"], link["masses"], link["n"]
            if not isinstance(p, int) or isinstance(p, bool):
                raise ValueError(f"{where}: field 'parent': expected an integer index of an earlier link or -1, got {p!r}")
            if not isinstance(s, int) or isinstance(s, bool):
                raise ValueError(f"{where}: field 'sign': expected +1 or -1, got {s!r}")
            if not isinstance(m, list) or len(m) != 3 or not all(_is_number(x) for x in m):
                raise ValueError(f"{where}: field 'masses': expected a list of three numbers [m0, m1, m2], got {m!r}")
            if not _is_number(f):
                raise ValueError(f"{where}: field 'n': expected a number in (0, 1), got {f!r}")
            parent.append(p); sign.append(s); masses.append(tuple(m)); frac.append(f)
            names.append(nm if nm is not None else f"link{i + 1}")
        name = str(data.get("name", "mechanism"))
        try:
            return cls(dim=dim, g=g, parent=tuple(parent), sign=tuple(sign), masses=tuple(masses),
                       n=tuple(frac), names=tuple(names), name=name)
        except ValueError as e:  # the same checks, reported against the file rather than the model name
            raise ValueError(f"{source}:" + str(e)[len(name) + 1:]) from None

    @classmethod
    def from_json(cls, text: str, source: str = "mechanism") -> "Mechanism":
        try:
            data = loads(text)
        except (json.JSONDecodeError, DuplicateKey) as e:
            raise ValueError(f"{source}: invalid JSON: {e}") from None
        return cls.from_dict(data, source)

    def replace(self, **changes: Any) -> "Mechanism":
        d = {f: getattr(self, f) for f in ("dim", "g", "parent", "sign", "masses", "n", "names", "name")}
        d.update(changes)
        return Mechanism(**d)


#: Why a negative g is refused (the choice is documented in docs/errors.md and tested).
_NEGATIVE_G = ("expected g >= 0: g is the magnitude of gravity, which acts along -y in 2D and -z in 3D by convention "
               "(a model that hangs from its support is described by its angles, not by reversing gravity)")

#: The largest force scale accepted: a bound on |tau| of ``1e300`` leaves float64 (largest 1.8e308)
#: a margin of 1e8 for the sums and products inside every method.
MAX_FORCE_SCALE = 1e300


def force_scale_log10(mech: "Mechanism", length: float = 1.0, rate: float = 1.0, acceleration: float = 1.0) -> float:
    """``log10`` of a bound on the generalised forces of ``mech`` at rod lengths up to ``length``,
    rates up to ``rate`` and accelerations up to ``acceleration``:
    ``total mass * n^2 * (1 + length)^2 * (1 + acceleration + rate^2 + g)``.

    Every term of the equations of motion is a mass times at most two lengths (summed over at most
    n links along a branch) times an acceleration, a squared rate or g, so ``|tau|`` is below this
    bound. Computed in logarithms, so it is finite for any finite input."""
    lg = lambda x: math.log10(x) if x > 0 else -math.inf
    n = max(len(mech.masses), 1)
    total_log = lg(max((max(m) for m in mech.masses), default=0.0)) + math.log10(3 * n)  # >= log10(total mass)
    dyn = max(0.0, lg(acceleration), 2 * lg(rate), lg(mech.g)) + math.log10(4)
    return total_log + 2 * math.log10(n) + 2 * lg(1.0 + length) + dyn


def _validate(m: Mechanism) -> None:
    """Check every field once; messages name the link, the field, expected and actual."""
    if m.dim not in (2, 3) or isinstance(m.dim, bool):
        raise ValueError(f"{m.name}: field 'dim': expected 2 or 3, got {m.dim!r}")
    if not _is_number(m.g) or not _finite(m.g):
        raise ValueError(f"{m.name}: field 'g': expected a finite number, got {m.g!r}")
    if m.g < 0:
        raise ValueError(f"{m.name}: field 'g': {_NEGATIVE_G}, got {m.g!r}")
    n = len(m.parent)
    if n == 0:
        raise ValueError(f"{m.name}: field 'links': expected at least one link, got none")
    for fld in ("sign", "masses", "n", "names"):
        if len(getattr(m, fld)) != n:
            raise ValueError(f"{m.name}: field '{fld}': expected {n} entries (one per link), got {len(getattr(m, fld))}")
    for i in range(n):
        where = f"{m.name}: {_where(i, m.names[i])}"
        nm = m.names[i]
        if not isinstance(nm, str) or any(ord(ch) < 32 or ord(ch) == 127 for ch in nm):
            raise ValueError(f"{where}: field 'name': expected a name without control characters (it is written "
                             f"into the URDF and the reports), got {nm!r}")
        p = m.parent[i]
        if not isinstance(p, (int, np.integer)) or isinstance(p, bool) or not (-1 <= p < i):
            if i == 0:
                expected = "-1 (the support: the first link has no earlier link to hang from)"
            else:
                expected = (f"-1 (the support) or the 0-based index of an earlier link, 0..{i - 1} "
                            f"(links 1..{i})")
            raise ValueError(f"{where}: field 'parent': expected {expected}, got {p!r}")
        s = m.sign[i]
        if isinstance(s, bool) or s not in (1, -1):
            raise ValueError(f"{where}: field 'sign': expected +1 or -1, got {s!r}")
        ms = m.masses[i]
        if len(ms) != 3:
            raise ValueError(f"{where}: field 'masses': expected three masses [m0, m1, m2], got {len(ms)}")
        for b, x in enumerate(ms):
            if not _is_number(x) or not _finite(x) or x < 0:
                raise ValueError(f"{where}: field 'masses[{b}]': expected a finite mass >= 0, got {x!r}")
        f = m.n[i]
        if not _is_number(f) or not _finite(f) or not (0.0 < f < 1.0):
            raise ValueError(f"{where}: field 'n': expected a fraction in (0, 1), got {f!r}")
    if all(x == 0 for ms in m.masses for x in ms):
        raise ValueError(f"{m.name}: field 'masses': expected at least one positive mass, got all zero")
    scale = force_scale_log10(m)
    if not scale < math.log10(MAX_FORCE_SCALE):
        big = max(max(ms) for ms in m.masses)
        raise ValueError(f"{m.name}: field 'masses': the forces of masses this large overflow float64 even at unit "
                         f"lengths and rates (largest mass {big:.3g} kg, force bound 1e{scale:.0f} > "
                         f"{MAX_FORCE_SCALE:.0e}); express the model in other units")


# --------------------------------------------------------------- coordinates
def coordinate_names(mech: Mechanism) -> list[str]:
    """Labels in block order: ``phi1..phin, psi1..psin, l1..ln`` (no psi in 2D)."""
    k = range(1, mech.nlinks + 1)
    blocks = ["phi", "psi", "l"] if mech.dim == 3 else ["phi", "l"]
    return [f"{b}{i}" for b in blocks for i in k]


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
    return q[..., :n], q[..., n:2 * n], q[..., 2 * n:]


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
                return (f"ragged rows: expected every row to have the same number of coordinates, got row 0 with "
                        f"{lengths[0]} and row {k} with {lengths[k]}")
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
    out = []
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
        if isinstance(arr, (list, tuple)):   # numpy takes true/false as 1.0/0.0: JSON booleans are not numbers
            where = _first_bool(arr)
            if where is not None:
                raise ValueError(f"{source}: field '{label}': expected numbers, got {where[0]!r} (a boolean) at "
                                 f"{where[1]}")
        if a.ndim == 1:
            a = a[None, :]
        if a.ndim == 2 and not a.flags.c_contiguous:
            a = np.ascontiguousarray(a)     # a DataFrame's values, a transpose, an .npz of asfortranarray
        if a.ndim != 2 or a.shape[1] != mech.dof:
            raise ValueError(
                f"{source}: field '{label}': expected shape (samples, {mech.dof}) in the order "
                f"{names[0]}..{names[-1]}, got {tuple(np.shape(arr))}")
        for s0 in range(0, a.shape[0], CHECK_ROWS):
            bad = ~np.isfinite(a[s0:s0 + CHECK_ROWS])
            if bad.any():
                s, c = map(int, np.argwhere(bad)[0])
                s += s0
                raise ValueError(f"{source}: field '{label}' sample {s} coordinate {names[c]}: "
                                 f"expected a finite number, got {a[s, c]}")
        out.append(a)
    shapes = {a.shape[0] for a in out if a is not None}
    if len(shapes) > 1:
        raise ValueError(f"{source}: q, qd and qdd must have the same number of samples, got {sorted(shapes)}")
    n = mech.nlinks
    length = rate = acceleration = 0.0
    for s0 in range(0, out[0].shape[0], CHECK_ROWS):
        l = out[0][s0:s0 + CHECK_ROWS, -n:]
        if (l < 0).any():
            s, i = map(int, np.argwhere(l < 0)[0])
            s += s0
            raise ValueError(f"{source}: field 'q' sample {s} coordinate l{i + 1} ({_where(i, mech.names[i])}): "
                             f"expected a rod length >= 0, got {l[s - s0, i]}")
        if l.size:
            length = max(length, float(l.max()))
        if out[1] is not None and out[1].size:
            rate = max(rate, float(np.abs(out[1][s0:s0 + CHECK_ROWS]).max()))
        if out[2] is not None and out[2].size:
            acceleration = max(acceleration, float(np.abs(out[2][s0:s0 + CHECK_ROWS]).max()))
    scale = force_scale_log10(mech, length, rate, acceleration)
    if not scale < math.log10(MAX_FORCE_SCALE):
        big = max(max(ms) for ms in mech.masses)
        raise ValueError(f"{source}: the forces would overflow float64: with masses up to {big:.3g} kg, "
                         f"rod lengths up to {length:.3g}, rates up to {rate:.3g} and accelerations up to "
                         f"{acceleration:.3g} the force bound is 1e{scale:.0f} > {MAX_FORCE_SCALE:.0e} "
                         "(models/mechanism.py force_scale_log10); express the states in other units")
    return tuple(out)
