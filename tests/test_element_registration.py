"""The rod elements (models/mechanism/rod_elements.py) are registered with numba once, however many kernel files
inline them (models/machine/numba_cache.py :func:`inline`).

Three files registered ``project_2d`` and ``project_3d``: the per-sample and the SIMD Newton-Euler kernels
(every element, each with its own ``register_jitable`` loop) and the f_ext kernel (through
``numba_cache.inline``). numba keeps each registration as one more overload template of the function
(three for the projections, two for the other elements), and the two Newton-Euler loops bypassed the
check that a function a kernel inlines is in that kernel's cache key. Now every kernel file declares what
it inlines through :func:`inline` (its cache key checked at each call) and each function is registered once.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from exo_bench.models.machine import numba_cache
from exo_bench.models.mechanism import rod_elements as el


def _templates(f) -> int:
    from numba.core.registry import cpu_target

    ctx = cpu_target.typing_context
    ctx.refresh()  # numba installs new registrations lazily
    return len(ctx._lookup_global(f).templates)


def test_every_rod_element_is_registered_with_numba_once():
    from exo_bench.models.runtime import external_forces_kernel  # noqa: F401 - each registers what it inlines
    from exo_bench.models.newton_euler import compiled, simd  # noqa: F401

    counts = {f.__name__: _templates(f) for f in el.ELEMENTS}
    assert counts == {f.__name__: 1 for f in el.ELEMENTS}, counts


def test_a_registered_function_is_still_checked_against_each_kernels_key(tmp_path):
    """Registering once does not skip the check: a kernel folder whose key lacks the elements' file is refused."""
    from exo_bench.models.newton_euler import compiled  # noqa: F401 - the projections are registered

    with pytest.raises(ValueError, match=r"project_2d of .*rod_elements\.py is inlined by the kernels of"):
        numba_cache.inline((el.project_2d,), Path(tmp_path))
