"""The form of the equations of motion, eq. (5) (2D) and eq. (17) (3D), defined once.

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
