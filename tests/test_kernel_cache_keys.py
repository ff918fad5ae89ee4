"""Every compiled kernel is keyed on the files it compiles in, checked without compiling anything.

The stale-cache probes (tests/test_compiled.py, tests/test_kernel_cache.py) edit an element file or the
shared sin/cos in a copy of the package and see one real kernel per mechanism path recompile: the
folder's key (models/machine/numba_cache.py, ``KernelSourceLocator``: the folder's modules, the files listed
for it in ``KERNEL_SOURCES`` and ``SHARED_SOURCES``). This file checks, for every ``cache=True``
kernel of every kernel folder, that it is keyed by that locator and that its key covers its own
file, the files listed for its folder and every shared source (the branch-free sin/cos among them),
so that what the probes show for one kernel holds for all of them.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest
from numba.core.registry import CPUDispatcher

from exo_bench.models.machine import fast_trig, numba_cache

ROOT = Path(numba_cache.__file__).resolve().parents[2]  # the folder holding models/ and matrix_method/


def _module_name(file: Path) -> str:
    return "exo_bench." + ".".join(file.relative_to(ROOT).with_suffix("").parts)


def _kernel_files() -> list[Path]:
    files = []
    for key in numba_cache.KERNEL_SOURCES:
        files += [key] if key.suffix == ".py" else sorted(p for p in key.glob("*.py") if p.name != "__init__.py")
    return files


def _cached_kernels(module) -> list:
    return [
        f
        for f in vars(module).values()
        if isinstance(f, CPUDispatcher) and f.__module__ == module.__name__ and f._cache._impl is not None
    ]


@pytest.mark.parametrize("file", _kernel_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_every_cached_kernel_is_keyed_on_its_inlined_and_shared_sources(file):
    module = importlib.import_module(_module_name(file))
    folder = file if file in numba_cache.KERNEL_SOURCES else file.parent
    wanted = {file, *numba_cache.KERNEL_SOURCES[folder], *numba_cache.SHARED_SOURCES}
    assert Path(fast_trig.__file__).resolve() in numba_cache.SHARED_SOURCES
    for f in _cached_kernels(module):
        locator = f._cache._impl.locator
        assert isinstance(locator, numba_cache.KernelSourceLocator), (file.name, f.__name__)
        assert locator._kernel_dir == folder, (file.name, f.__name__, locator._kernel_dir)
        assert wanted <= set(numba_cache.inlined_sources(locator._kernel_dir)), (file.name, f.__name__)


def test_the_kernels_of_both_families_simd_modules_are_among_them():
    """The SIMD kernels that call ``sincos_reduced`` (the stale-cache probe of the shared sin/cos runs one
    of them) are cached kernels of the files checked above."""
    from exo_bench.matrix_method.numba_kernels import simd as factored_simd
    from exo_bench.models.machine import simd_blocks
    from exo_bench.models.newton_euler import simd as ne_simd

    assert simd_blocks.sincos_reduced is fast_trig.sincos_reduced  # the angles of both families' blocks
    assert {Path(m.__file__).resolve() for m in (simd_blocks, fast_trig)} <= set(numba_cache.SHARED_SOURCES)
    assert {Path(m.__file__).resolve() for m in (factored_simd, ne_simd)} <= set(_kernel_files())
    for module in (factored_simd, ne_simd):
        assert _cached_kernels(module), module.__name__
