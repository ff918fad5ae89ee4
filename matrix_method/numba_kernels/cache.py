"""numba's on-disk cache for the matrix family's kernels, keyed on the source of every function a
kernel inlines (the locator is :mod:`exo_bench.models.machine.numba_cache`, which lists this folder and the
files its kernels inline in ``KERNEL_SOURCES``): an edit to a closed form in
:mod:`exo_bench.matrix_method.closed_forms.planar` or ``transitions``, which the kernels inline
through ``register_jitable``, recompiles the kernels instead of loading stale machine code.
tests/test_compiled.py edits an element function in a copy of the package and sees the new forces
from the compiled kernel.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from exo_bench.models.machine import numba_cache
from exo_bench.models.machine.numba_cache import KernelSourceLocator  # noqa: F401 - re-exported

#: Where the kernels live: a kernel defined in a file of this folder uses the locator.
KERNELS_DIR = Path(__file__).resolve().parent


def inline(functions: Iterable[Callable[..., Any]], always: bool = False) -> None:
    """:func:`exo_bench.models.machine.numba_cache.inline` for the kernels of this folder."""
    numba_cache.inline(functions, KERNELS_DIR, always)


def inlined_sources() -> list[Path]:
    """The source files the kernels of this folder depend on."""
    return numba_cache.inlined_sources(KERNELS_DIR)


def inlined_sources_hash() -> str:
    return numba_cache.inlined_sources_hash(KERNELS_DIR)
