"""The f_ext kernel (models/runtime/external_forces_kernel.py) projects with the rod elements' own functions
(models/mechanism/rod_elements.py ``project_2d``/``project_3d``): nothing physical is written twice, and numba's
on-disk cache of the kernel is keyed on the elements' file too, so an edit there recompiles the kernel
instead of loading stale machine code (models/machine/numba_cache.py)."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

from exo_bench.models.runtime import external_forces_kernel
from exo_bench.models.machine import numba_cache
from exo_bench.models.mechanism import rod_elements


def _called_names(module) -> set[str]:
    tree = ast.parse(inspect.getsource(module))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            names.add(f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", ""))
    return names


def test_the_kernel_calls_the_rod_projections():
    assert {"project_2d", "project_3d"} <= _called_names(external_forces_kernel)


def test_the_kernel_cache_is_keyed_on_the_rod_elements():
    from exo_bench.models.machine.numba_runtime import ensure

    ensure()  # numba's locators installed, as before any kernel is defined
    kernel_file = Path(external_forces_kernel.__file__).resolve()
    py_func = getattr(external_forces_kernel.apply, "py_func", external_forces_kernel.apply)
    locator = numba_cache.KernelSourceLocator.from_function(py_func, str(kernel_file))
    assert locator is not None, "the f_ext kernel's cache is keyed on its own file only"
    sources = numba_cache.inlined_sources(locator._kernel_dir)
    assert kernel_file in sources
    assert Path(rod_elements.__file__).resolve() in sources
    # its own file and what it inlines, not every module of models/
    assert Path(numba_cache.__file__).resolve().parents[1] / "runtime" / "prepared.py" not in sources
