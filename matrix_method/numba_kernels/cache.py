"""numba's on-disk cache keyed on the source of every function a kernel inlines.

numba keys a cached kernel on its own file only (the source stamp of its cache index): an edit to
a closed form in :mod:`exo_bench.matrix_method.closed_forms.planar` or ``transitions``, which the
kernels inline through ``register_jitable``, or an upgrade that changes only those files, would
leave the old machine code serving wrong forces, silently. :class:`KernelSourceLocator` wraps
numba's own locator for the kernel files of this package (same cache folder, same file names) and
adds to the source stamp a hash of the sources of every module whose functions the kernels inline
(:func:`inlined_sources`): any edit there makes the index's stamp differ, so numba recompiles and
overwrites the entry instead of loading it. It is put first in numba's list of locators when this
module is imported (before any kernel is defined); tests/test_compiled.py edits an element function
in a copy of the package and sees the new forces from the compiled kernel.

numba's documentation says a cached function is invalidated "when the corresponding source file is
modified" and that changes to functions it calls in other files are not detected; this closes that
gap for our kernels (numba/core/caching.py: ``_CacheLocator.get_source_stamp``, ``CacheImpl._locator_classes``).
"""

from __future__ import annotations

import functools
import hashlib
import inspect
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from numba.core import caching
from numba.extending import register_jitable

_CacheLocator = caching._CacheLocator
#: numba's cache implementation, whose ``_locator_classes`` lists the locators tried in order
#: (``CacheImpl`` in numba 0.68; ``_CacheImpl`` before).
_CacheImpl: Any = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl")  # noqa: B009

#: Where the kernels live: a kernel defined in a file of this folder uses :class:`KernelSourceLocator`.
KERNELS_DIR = Path(__file__).resolve().parent
_INLINED: dict[str, None] = {}   # the source files of the functions registered with :func:`inline` (ordered)


def inline(functions: Iterable[Callable[..., Any]], always: bool = False) -> None:
    """Register ``functions`` with numba (``register_jitable``: callable from a kernel, and still plain
    Python for numpy and sympy) and key the kernels' cache on their source files; ``always``: inline
    them in numba's IR (the generated call lists, which must compile as if written out)."""
    for f in functions:
        if always:
            register_jitable(inline="always")(f)
        else:
            register_jitable(f)
        _INLINED[str(Path(inspect.getfile(f)).resolve())] = None
    inlined_sources_hash.cache_clear()


def inlined_sources() -> list[Path]:
    """The source files the kernels depend on: every module of this folder and the modules of the
    registered element functions."""
    own = sorted(p.resolve() for p in KERNELS_DIR.glob("*.py"))
    return own + [Path(p) for p in _INLINED if Path(p) not in own]


@functools.lru_cache(maxsize=1)
def inlined_sources_hash() -> str:
    h = hashlib.sha256()
    for p in inlined_sources():
        h.update(str(p.name).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


class KernelSourceLocator(_CacheLocator):
    """numba's own locator for a kernel file of this package, with a source stamp that also covers
    :func:`inlined_sources`."""

    def __init__(self, inner: _CacheLocator) -> None:
        self._inner = inner

    def ensure_cache_path(self) -> None:
        self._inner.ensure_cache_path()

    def get_cache_path(self) -> str:
        return self._inner.get_cache_path()

    def get_disambiguator(self) -> str:
        return self._inner.get_disambiguator()

    def get_source_stamp(self) -> Any:
        return (self._inner.get_source_stamp(), inlined_sources_hash())

    @classmethod
    def from_function(cls, py_func: Callable[..., Any], py_file: str) -> KernelSourceLocator | None:
        try:
            if Path(py_file).resolve().parent != KERNELS_DIR:
                return None
        except OSError:
            return None
        for base in _CacheImpl._locator_classes:
            if base is cls:
                continue
            inner = base.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner)
        return None


if KernelSourceLocator not in _CacheImpl._locator_classes:
    _CacheImpl._locator_classes.insert(0, KernelSourceLocator)
