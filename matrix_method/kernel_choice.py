"""The ``kernel`` option of the matrix family: its values, and its check."""

from __future__ import annotations

#: The values of the option ``kernel``: compiled loops (numba, the default), or the numpy kernels.
KERNEL_CHOICES: tuple[str, ...] = ("numba", "numpy")


def kernel_option(method: str, kernel: object) -> str:
    """``kernel`` if it is one of :data:`KERNEL_CHOICES`, else a ValueError naming the method."""
    if not isinstance(kernel, str) or kernel not in KERNEL_CHOICES:
        raise ValueError(
            f"{method}: option 'kernel': expected one of {', '.join(map(repr, KERNEL_CHOICES))}, got {kernel!r}"
        )
    return kernel
