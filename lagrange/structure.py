"""Lagrange derivation, the data: what a derivation depends on (:class:`Structure`: dim, parent,
sign, which masses are zero) and what it produces (:class:`Derivation`); the block order and matrix
names come from :mod:`models.equation_form`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from dataclasses import dataclass
from dataclasses import field
from functools import cached_property


import sympy as sp

from exo_bench.models.equation_form import blocks
from exo_bench.models.equation_form import matrix_names
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.symbols import Symbols

if TYPE_CHECKING:
    from exo_bench.lagrange.ring import _RingForm


#: blocks of coordinates (rows of the matrix form), in block order
BLOCKS = {dim: blocks(dim) for dim in (2, 3)}   # models.equation_form: the block order, defined once


#: names of the matrices of eq. (5) (2D) and eq. (17) (3D)
MATRIX_NAMES = {dim: (*matrix_names(dim), "P") for dim in (2, 3)}


ENGINES = ("poly", "expr")


class FormViolation(ValueError):
    """An equation has a term that the paper's matrix form (eqs. 5, 17) cannot hold."""


# ------------------------------------------------------------------ structure
@dataclass(frozen=True)
class Structure:
    """What the symbolic derivation depends on: the tree, the signs and the zero masses."""

    dim: int
    parent: tuple[int, ...]
    sign: tuple[int, ...]
    zero_masses: tuple[tuple[bool, bool, bool], ...]

    @property
    def nlinks(self) -> int:
        return len(self.parent)


def structure_of(mech: Mechanism) -> Structure:
    return Structure(mech.dim, mech.parent, mech.sign,
                     tuple(tuple(m == 0.0 for m in ms) for ms in mech.masses))


# ------------------------------------------------------------------ result
@dataclass(frozen=True, eq=False)
class Derivation:
    """Lagrange II for one mechanism (or one structure, with symbolic parameters).

    ``equations[a]`` is the generalised force of coordinate ``a`` (block order, as ``tau``);
    ``matrices[block][name]`` the paper's matrices (``P`` is ``(n, 1)`` and excludes ``g``);
    ``seconds`` the wall time of each phase when this result was first computed.
    """

    structure: Structure
    symbols: Symbols
    equations: tuple[sp.Expr, ...]
    matrices: dict[str, dict[str, sp.Matrix]]
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    symbolic_parameters: bool
    engine: str
    seconds: dict[str, float] = field(default_factory=dict)
    ring_form: "_RingForm | None" = field(default=None, repr=False)   # internal: the ring elements
    values: dict = field(default_factory=dict, repr=False)   # the substituted parameter values ({} if symbolic)

    @property
    def g(self) -> sp.Expr:
        """The gravity factor in front of ``P``: the symbol ``g``, or its substituted value."""
        return self.values.get(self.symbols.g, self.symbols.g)

    @property
    def dim(self) -> int:
        return self.structure.dim

    @property
    def nlinks(self) -> int:
        return self.structure.nlinks

    @cached_property
    def mass_matrix(self) -> sp.Matrix:
        """``(dof, dof)``: row block k is ``[A_k, B_k, Lambda_k]`` (``[A_k, Lambda_k]`` in 2D)."""
        cols = ("A", "B", "Lambda") if self.dim == 3 else ("A", "Lambda")
        return sp.Matrix.vstack(*[sp.Matrix.hstack(*[self.matrices[k][c] for c in cols])
                                  for k in BLOCKS[self.dim]])

