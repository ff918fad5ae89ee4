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
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from exo_bench.models.files import check_name
from exo_bench.models.states.validation import (
    _NEGATIVE_G,
    DuplicateKey,
    _finite,
    _is_number,
    _where,
    loads,
    validate,
)

_LINK_KEYS = {"parent", "sign", "masses", "n"}
_LINK_OPTIONAL = {"name"}
_TOP_KEYS = {"dim", "g", "links"}
_TOP_OPTIONAL = {"name"}


def _read_only(a: np.ndarray) -> np.ndarray:
    """A read-only view of ``a``, itself made read-only: numpy lets the owner of the data set its
    write flag again, but not a view of a read-only base."""
    a.flags.writeable = False
    view = a.view()
    view.flags.writeable = False
    return view


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
        validate(self)
        # Store plain Python numbers (numpy scalars would leak into JSON and hashes).
        object.__setattr__(self, "parent", tuple(int(p) for p in self.parent))
        object.__setattr__(self, "sign", tuple(int(s) for s in self.sign))
        object.__setattr__(self, "masses", tuple(tuple(float(x) for x in m) for m in self.masses))
        object.__setattr__(self, "n", tuple(float(x) for x in self.n))
        object.__setattr__(self, "g", float(self.g) + 0.0)  # -0.0 -> 0.0: one mechanism, one hash
        object.__setattr__(self, "dim", int(self.dim))

    @cached_property
    def _hash(self) -> int:
        return hash((self.dim, self.g, self.parent, self.sign, self.masses, self.n, self.names, self.name))

    def __hash__(self) -> int:  # cached: models, URDFs and derivations are looked up by mechanism
        return self._hash

    def __reduce__(self) -> tuple[type[Mechanism], tuple]:
        """Pickled as its fields alone and rebuilt (so validated) where it is unpickled: the caches
        stay behind, the hash above among them, whose string hashes differ between processes."""
        return (
            type(self),
            (self.dim, self.g, self.parent, self.sign, self.masses, self.n, self.names, self.name),
        )

    # ----------------------------------------------------------------- sizes
    @property
    def nlinks(self) -> int:
        return len(self.parent)

    @property
    def dof(self) -> int:
        """Number of generalised coordinates: 2n in 2D, 3n in 3D."""
        return self.dim * self.nlinks

    # ------------------------------------------------------ numpy views
    # Read-only, like the frozen fields they are built from: every method reads them (some once at
    # prepare, some at every call), so a write would change some methods and not others.
    @cached_property
    def mass_array(self) -> np.ndarray:
        """``(n, 3)`` array of ``[m_i0, m_i1, m_i2]``, read-only."""
        return _read_only(np.array(self.masses, dtype=float))

    @cached_property
    def fractions(self) -> np.ndarray:
        """``(n, 3)`` array of ``[n_i0, n_i1, n_i2] = [0, n_i, 1]``, read-only."""
        f = np.zeros((self.nlinks, 3))
        f[:, 1] = self.n
        f[:, 2] = 1.0
        return _read_only(f)

    @cached_property
    def sign_array(self) -> np.ndarray:
        """``(n,)`` array of the branch signs, read-only."""
        return _read_only(np.array(self.sign, dtype=float))

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
        return _read_only(a)

    def is_chain(self) -> bool:
        """True for a serial chain ``parent = (-1, 0, 1, ..., n-2)``."""
        return self.parent == tuple(range(-1, self.nlinks - 1))

    # ------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        links = []
        for i in range(self.nlinks):
            links.append(
                {
                    "name": self.names[i],
                    "parent": self.parent[i],
                    "sign": self.sign[i],
                    "masses": list(self.masses[i]),
                    "n": self.n[i],
                }
            )
        return {"name": self.name, "dim": self.dim, "g": self.g, "links": links}

    def to_json(self, indent: int | None = 1) -> str:
        return json.dumps(self.to_dict(), indent=indent)

    @classmethod
    def from_dict(cls, data: Any, source: str = "mechanism") -> Mechanism:
        """Build from the JSON format, validating every field with a message that
        names the link, the field, and the expected and actual values."""
        if not isinstance(data, dict):
            raise ValueError(
                f"{source}: expected a JSON object with keys {sorted(_TOP_KEYS)}, got {type(data).__name__}"
            )
        missing = _TOP_KEYS - data.keys()
        if missing:
            raise ValueError(
                f"{source}: missing key(s) {sorted(missing)}: expected an object with keys {sorted(_TOP_KEYS)}"
            )
        extra = data.keys() - _TOP_KEYS - _TOP_OPTIONAL
        if extra:
            raise ValueError(
                f"{source}: unknown key(s) {sorted(extra)}: expected only {sorted(_TOP_KEYS | _TOP_OPTIONAL)}"
            )
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
            if nm is not None:
                check_name(nm, f"{where}: field 'name'")
            where = f"{source}: {_where(i, nm)}"
            missing = _LINK_KEYS - link.keys()
            if missing:
                raise ValueError(f"{where}: missing field(s) {sorted(missing)}: expected keys {sorted(_LINK_KEYS)}")
            extra = link.keys() - _LINK_KEYS - _LINK_OPTIONAL
            if extra:
                raise ValueError(
                    f"{where}: unknown field(s) {sorted(extra)}: expected only {sorted(_LINK_KEYS | _LINK_OPTIONAL)}"
                )
            p, s, m, f = link["parent"], link["sign"], link["masses"], link["n"]
            if not isinstance(p, int) or isinstance(p, bool):
                raise ValueError(
                    f"{where}: field 'parent': expected an integer index of an earlier link or -1, got {p!r}"
                )
            if not isinstance(s, int) or isinstance(s, bool):
                raise ValueError(f"{where}: field 'sign': expected +1 or -1, got {s!r}")
            if not isinstance(m, list) or len(m) != 3 or not all(_is_number(x) for x in m):
                raise ValueError(f"{where}: field 'masses': expected a list of three numbers [m0, m1, m2], got {m!r}")
            if not _is_number(f):
                raise ValueError(f"{where}: field 'n': expected a number in (0, 1), got {f!r}")
            parent.append(p)
            sign.append(s)
            masses.append(tuple(m))
            frac.append(f)
            names.append(nm if nm is not None else f"link{i + 1}")
        name = check_name(data.get("name", "mechanism"), f"{source}: field 'name'")  # not str(): no dict or number
        try:
            return cls(
                dim=dim,
                g=g,
                parent=tuple(parent),
                sign=tuple(sign),
                masses=tuple(masses),
                n=tuple(frac),
                names=tuple(names),
                name=name,
            )
        except ValueError as e:  # the same checks, reported against the file rather than the model name
            raise ValueError(f"{source}:" + str(e)[len(name) + 1 :]) from None

    @classmethod
    def from_json(cls, text: str, source: str = "mechanism") -> Mechanism:
        try:
            data = loads(text)
        except (json.JSONDecodeError, DuplicateKey) as e:
            raise ValueError(f"{source}: invalid JSON: {e}") from None
        return cls.from_dict(data, source)

    def replace(self, **changes: Any) -> Mechanism:
        d = {f: getattr(self, f) for f in ("dim", "g", "parent", "sign", "masses", "n", "names", "name")}
        d.update(changes)
        return Mechanism(**d)
