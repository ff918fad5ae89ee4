"""numba's threads, shared by every compiled kernel of the suite: the layer, the jit options and
the one driver lock.

Kept in the lowest layer (``models``) so that the matrix family (:mod:`exo_bench.matrix_method.numba_kernels.common`)
and the Newton-Euler kernels (:mod:`exo_bench.models.newton_euler.compiled`) choose the same threading layer
before either starts numba's threads, and share one lock: ``workqueue`` aborts the process on
concurrent parallel launches, whichever kernel makes them. Why ``workqueue`` and why
:data:`PARALLEL_MIN_SAMPLES`: :mod:`exo_bench.matrix_method.numba_kernels.common`.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypedDict

import numba
from numba import njit

from exo_bench.models import numba_cache

#: numba.config sets its options at run time (the stubs do not list them).
config: Any = numba.config


def _threading_layer() -> str:
    """Choose numba's ``workqueue`` threading layer (module docstring) when nobody chose one yet;
    return the layer numba will use (or uses)."""
    try:
        from numba.np.ufunc import parallel

        started = bool(parallel._is_initialized)
    except (ImportError, AttributeError):
        started = True
    if not started and "NUMBA_THREADING_LAYER" not in os.environ:
        config.THREADING_LAYER = "workqueue"
    return str(config.THREADING_LAYER)


THREADING_LAYER = _threading_layer()


#: The jit options of every kernel: machine code cached on disk, exact IEEE arithmetic (no
#: fastmath: the kernels are held to the numpy reference at 1e-14).
class JitOptions(TypedDict):
    cache: bool
    nogil: bool


JIT: JitOptions = {"cache": True, "nogil": True}


def jit_for(lanes: int) -> Callable[[Callable[..., Any]], Any]:
    """``njit(**JIT)`` for a closure of a kernel factory built for blocks of ``lanes`` samples, under a
    qualified name that carries ``lanes`` (``build.<locals>._backward`` becomes ``..._backward_16lanes``).

    numba names a compiled function's symbol after its qualified name and a per-process counter, and
    :mod:`exo_bench.models.numba_cache` lets these closures hit the on-disk cache in every process.
    The same closure built for 16 and for 32 lanes, each compiled first in a different process, could
    then get the same symbol with different machine code, and a process that loaded both from the
    cache called one for the other: ``newton-euler`` on a 3D chain of 900 links segfaulted after a
    batch on exo5-3d, or LLVM aborted with "No name entry found!" (numba issue #10486). With the
    block size in the name, two closures that share a symbol have the same source and block size, so
    the same code. tests/test_kernel_cache.py reproduces the three processes."""

    def decorate(fn: Callable[..., Any]) -> Any:
        fn.__qualname__ = f"{fn.__qualname__}_{lanes}lanes"
        return njit(**JIT)(fn)

    return decorate


#: Samples per task of the parallel driver (each task allocates its scratch once): a group of samples,
#: not a coordinate block.
SAMPLES_PER_TASK = 64
#: Batches of at least this many samples run the parallel driver. Below it, waking numba's threads
#: costs more than it saves: on the 2-core machine (quiet) exo5-3d took 0.12 us/sample serial at
#: every size, and in parallel 0.20-0.34 us/sample at 600-2048 samples, 0.09-0.17 at 4096, 0.08 at
#: 8192, 0.07 at 10,000-20,000.
PARALLEL_MIN_SAMPLES = 4096

_PARALLEL = threading.Lock()


def run(serial, parallel, args: tuple, samples: int):
    """``serial(*args)``, or ``parallel(*args)`` for a batch of at least :data:`PARALLEL_MIN_SAMPLES`
    samples when no other thread is in a parallel driver (then the serial one: same result)."""
    if samples >= PARALLEL_MIN_SAMPLES and _PARALLEL.acquire(blocking=False):
        try:
            return parallel(*args)
        finally:
            _PARALLEL.release()
    return serial(*args)


#: newton-euler's kernels (models/newton_euler/compiled.py, which imports this module for :data:`JIT`)
#: inline the element functions of their own folder: numba's cache is keyed on that whole folder
#: (:mod:`exo_bench.models.numba_cache`), so an edit to elements.py recompiles them.
NEWTON_EULER_KERNELS = numba_cache.register_kernel_dir(Path(__file__).resolve().parent / "newton_euler")
