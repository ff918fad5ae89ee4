"""numba's runtime set-up, in one place: :func:`ensure`, which every module that defines compiled kernels
calls before its first kernel, and :meth:`exo_bench.api.methods.MethodSpec.load` before it imports a
method with compiled kernels. Importing this module imports no numba and changes nothing.

:func:`ensure` is idempotent (each step looks at numba's own state first) and has these effects, in
this order:

1. **Checks numba's environment** (:func:`environment_problem`), before numba is imported where it is
   the first to import it: a bad ``NUMBA_NUM_THREADS`` or ``NUMBA_THREADING_LAYER`` is one ValueError
   naming the variable (issue 34, U6), not numba's own failure at import or at the first parallel launch.
2. **Keys numba's on-disk cache on every source a kernel inlines** (patch of numba's internals):
   :class:`exo_bench.models.machine.numba_cache.KernelSourceLocator` is put first in numba's list of cache
   locators (``CacheImpl._locator_classes``, numba/core/caching.py). It serves the kernel folders of
   :data:`exo_bench.models.machine.numba_cache.KERNEL_SOURCES` only; a locator is chosen when a kernel is
   defined (``cache=True``), hence "before its first kernel". Second in that list,
   :class:`exo_bench.models.machine.numba_cache.InstalledCacheLocator` keeps an installed copy's cache beside
   the package, not inside it (a later editable install is not shadowed by what pip leaves behind).
3. **Keys closures by their code** (patch): numba's ``FunctionCache._index_key`` is wrapped by
   :func:`exo_bench.models.machine.numba_cache.index_key_by_code`, so that the closures of a kernel folder
   hit the cache in every process (numba's own key for every other function).
4. **Lets one process at a time write a cache index** (patch): numba's ``IndexDataCacheFile.save`` and
   ``.load`` hold a lock on the index (:func:`exo_bench.models.machine.numba_cache.index_locked`), so that
   processes sharing a cache folder (two commands in one checkout, Dask workers, the test suite's
   workers) never lose a kernel or pair an index entry with another signature's machine code.
5. **Chooses numba's threading layer** (numba's config): ``workqueue``, unless the user chose one
   (``NUMBA_THREADING_LAYER``) or numba's threads already run (then numba keeps its own). Why
   ``workqueue``: :mod:`exo_bench.matrix_method.numba_kernels.common`.

Also here, shared by the matrix family (:mod:`exo_bench.matrix_method.numba_kernels.common`) and the
Newton-Euler kernels (:mod:`exo_bench.models.newton_euler.compiled`): the jit options (:data:`JIT`,
:func:`jit_for`), the parallel driver's thresholds and :func:`run`, and the one state of this module,
:data:`RUNTIME` (the lock of the parallel drivers, and the Python thread pool of the SIMD drivers).
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypedDict

from exo_bench.models.machine.memory import count_problem

#: numba's threading layers (``NUMBA_THREADING_LAYER``) and the libraries that can serve each on Linux
#: (numba/np/ufunc/parallel.py, ``_launch_threads``: "safe" is TBB, "threadsafe" TBB or OpenMP,
#: "forksafe" TBB or workqueue, "default" any).
LAYERS: dict[str, tuple[str, ...]] = {
    "default": ("tbb", "omp", "workqueue"),
    "safe": ("tbb",),
    "threadsafe": ("tbb", "omp"),
    "forksafe": ("tbb", "workqueue"),
    "workqueue": ("workqueue",),
    "omp": ("omp",),
    "tbb": ("tbb",),
}


def environment_problem(environ: Mapping[str, str] = os.environ) -> str | None:
    """Why numba's environment cannot run the compiled kernels, in one line naming the variable, its
    value and what is expected (None: it can). Checked before numba is imported (numba itself fails
    on ``NUMBA_NUM_THREADS=0`` at import, and on an unknown or missing threading layer only at the
    first parallel launch, neither naming the variable): ``NUMBA_NUM_THREADS`` is a count like every
    thread count (:func:`exo_bench.models.machine.memory.max_count`), ``NUMBA_THREADING_LAYER`` one of
    :data:`LAYERS` whose library loads here (not checked once numba's threads run: the layer is chosen)."""
    text = environ.get("NUMBA_NUM_THREADS")
    if text is not None:
        try:
            value: object = int(text)
        except ValueError:
            value = text
        problem = count_problem(value, "threads")
        if problem:
            return f"NUMBA_NUM_THREADS={text!r}: numba's threads: {problem}"
    layer = environ.get("NUMBA_THREADING_LAYER")
    if layer is None or _threads_started():
        return None
    libraries = LAYERS.get(layer.lower())  # numba lower-cases it
    if libraries is None:
        return f"NUMBA_THREADING_LAYER={layer!r}: expected one of numba's threading layers: {', '.join(LAYERS)}"
    if not any(_loads(lib) for lib in libraries):
        here = [name for name, libs in LAYERS.items() if any(_loads(lib) for lib in libs)]
        hint = " (Intel TBB: pip install tbb)" if "tbb" in libraries else ""
        return (
            f"NUMBA_THREADING_LAYER={layer!r}: its library ({' or '.join(libraries)}) does not load here{hint}; "
            f"expected one that does: {', '.join(here)}"
        )
    return None


def check_environment(environ: Mapping[str, str] = os.environ) -> None:
    """A ValueError with :func:`environment_problem`'s line, if any."""
    problem = environment_problem(environ)
    if problem:
        raise ValueError(problem)


def _threads_started() -> bool:
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    return bool(getattr(parallel, "_is_initialized", False))


def _loads(library: str) -> bool:
    """numba's threading library ``library`` (tbb, omp, workqueue) loads in this process."""
    try:
        if library == "tbb":
            from numba.np.ufunc.parallel import _check_tbb_version_compatible

            _check_tbb_version_compatible()
        importlib.import_module("numba.np.ufunc." + ("workqueue" if library == "workqueue" else f"{library}pool"))
    except ImportError:
        return False
    return True


def ensure() -> str:
    """numba's runtime set-up (the module docstring lists its effects); returns the threading layer numba
    will use (or uses). Idempotent: the patches are installed once, the layer chosen once."""
    check_environment()
    import numba
    from numba.core import caching as numba_caching

    from exo_bench.models.machine.numba_cache import (
        InstalledCacheLocator,
        KernelSourceLocator,
        index_key_by_code,
        index_locked,
    )

    caching: Any = numba_caching  # its internals, which numba's type hints do not describe
    impl = caching.CacheImpl if hasattr(caching, "CacheImpl") else caching._CacheImpl  # (numba < 0.68)
    if KernelSourceLocator not in impl._locator_classes:
        impl._locator_classes.insert(0, KernelSourceLocator)
    if InstalledCacheLocator not in impl._locator_classes:  # before numba's own (the kernels' locator wraps it)
        impl._locator_classes.insert(1, InstalledCacheLocator)
    if not getattr(caching.FunctionCache._index_key, "keyed_by_code", False):
        caching.FunctionCache._index_key = index_key_by_code(caching.FunctionCache._index_key)
    cache_file = caching.IndexDataCacheFile
    if not getattr(cache_file.save, "index_locked", False):
        cache_file.save = index_locked(cache_file.save, shared=False)
        cache_file.load = index_locked(cache_file.load, shared=True)
    config: Any = numba.config  # numba.config sets its options at run time (the stubs do not list them)
    if not _threads_started() and "NUMBA_THREADING_LAYER" not in os.environ:
        config.THREADING_LAYER = "workqueue"
    return str(config.THREADING_LAYER)


def jit_disabled() -> bool:
    """``NUMBA_DISABLE_JIT`` is set: numba runs its functions as Python, and the kernels' SIMD tiles
    (numba intrinsics: models/machine/simd_blocks.py) cannot run at all."""
    import numba

    return bool(getattr(numba.config, "DISABLE_JIT"))  # noqa: B009 - set at run time


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
    :mod:`exo_bench.models.machine.numba_cache` lets these closures hit the on-disk cache in every process.
    The same closure built for 16 and for 32 lanes, each compiled first in a different process, could
    then get the same symbol with different machine code, and a process that loaded both from the
    cache called one for the other: ``newton-euler`` on a 3D chain of 900 links segfaulted after a
    batch on exo5-3d, or LLVM aborted with "No name entry found!" (numba issue #10486). With the
    block size in the name, two closures that share a symbol have the same source and block size, so
    the same code. tests/test_kernel_cache.py reproduces the three processes."""

    def decorate(fn: Callable[..., Any]) -> Any:
        ensure()  # before numba chooses the kernel's cache locator
        from numba import njit

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


class Runtime:
    """The state of numba's runtime that is ours (one instance, :data:`RUNTIME`): the lock that lets
    one Python thread at a time into a parallel driver (``workqueue`` aborts the process on concurrent
    parallel launches, whichever kernel makes them), and the Python thread pool of the SIMD drivers
    (:func:`exo_bench.models.machine.simd_blocks.run`), made at its first use and grown when more threads are asked."""

    def __init__(self) -> None:
        self.parallel = threading.Lock()
        self._pool: ThreadPoolExecutor | None = None
        self._pool_lock = threading.Lock()

    def pool(self, workers: int) -> ThreadPoolExecutor:
        """A pool of at least ``workers`` threads."""
        with self._pool_lock:
            if self._pool is None or self._pool._max_workers < workers:
                self._pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="exo-bench-simd")
            return self._pool


#: numba's runtime state that is ours: the only mutable object of the module.
RUNTIME = Runtime()


def run(serial, parallel, args: tuple, samples: int):
    """``serial(*args)``, or ``parallel(*args)`` for a batch of at least :data:`PARALLEL_MIN_SAMPLES`
    samples when no other thread is in a parallel driver (then the serial one: same result)."""
    if samples >= PARALLEL_MIN_SAMPLES and RUNTIME.parallel.acquire(blocking=False):
        try:
            return parallel(*args)
        finally:
            RUNTIME.parallel.release()
    return serial(*args)
