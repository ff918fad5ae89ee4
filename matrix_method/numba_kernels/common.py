"""Compiled (numba) kernels of the matrix family: what they share.

The kernels themselves, one algorithm per file:

* :mod:`exo_bench.matrix_method.numba_kernels.factored` (method ``matrix-factored``): eq. (5)/(17) in factored
  form, no matrix formed (the derivation is in :func:`exo_bench.matrix_method.numpy_kernels.matrix.inverse_dynamics`);
* :mod:`exo_bench.matrix_method.numba_kernels.matrix` (method ``matrix``): every matrix of eq. (5)/(17) formed
  from the closed forms of :mod:`exo_bench.matrix_method.closed_forms.planar` and :mod:`exo_bench.matrix_method.closed_forms.transitions`, then the
  products with the rates of :data:`exo_bench.models.states.states.RATES`;
* :mod:`exo_bench.matrix_method.numba_kernels.recurrence` (method ``recurrence``): the planar matrices grown link
  by link by eqs. (22)-(26), then the same transitions and products.

The pure-numpy kernels (:mod:`exo_bench.matrix_method.numpy_kernels.matrix`, :mod:`exo_bench.matrix_method.recurrence`) stay the
reference implementation; tests/test_compiled.py holds these to them at 1e-14 relative.

**One kernel, one sample or a batch.** Each algorithm is a per-sample function, a function
that runs it over samples ``start .. stop - 1`` with its scratch allocated once, and two drivers
``kernel(*args, q, qd, qdd, o)`` that write the forces into ``o``; states and forces are flat,
C-ordered ``(samples * dof,)`` float64 arrays (a ``(dof,)`` sample is already one, a
``(samples, dof)`` batch is its ``reshape(-1)``, a view): one signature per kernel. The serial
driver runs them all; for batches of at least
:data:`exo_bench.models.machine.numba_runtime.PARALLEL_MIN_SAMPLES` samples the parallel driver runs tasks
of :data:`exo_bench.models.machine.numba_runtime.SAMPLES_PER_TASK` samples over numba's threads (``prange``). Writing into a
given ``o`` (no array returned) leaves a one-sample call with numba's dispatch and the arithmetic
only (returning a new array cost about as much as the arithmetic of exo5-3d): the caller may
preallocate it (``inverse_dynamics(..., out=)``).

**Closed forms written once.** The compiled ``matrix`` and ``recurrence`` kernels call the very
functions of :mod:`exo_bench.matrix_method.closed_forms.planar` and :mod:`exo_bench.matrix_method.closed_forms.transitions` (registered here with
``numba.extending.register_jitable``, which leaves them plain Python functions for numpy and
sympy); the transitions take their namespace ``t`` as a namedtuple (:data:`Transition`).

**Compile once per machine.** ``cache=True`` writes the machine code beside this package
(``__pycache__``, or numba's user-wide cache folder where that is not writable), so a second
process loads it instead of compiling. The first call of each kernel in a fresh cache compiles it
(1 to 10 s each on the 2-core machine, the ``compile`` table of reports/scaling.md, measured by
:func:`compile_times`). The cache is keyed on the source of every function a kernel inlines, not
only on the kernel's own file (:func:`inline`, below): an edit to a
closed form recompiles the kernels that use it.

**Threads.** (``matrix-factored``'s batches run :mod:`exo_bench.matrix_method.numba_kernels.simd` instead, on a
Python thread pool that never enters numba's threading layer.) The parallel drivers run on numba's ``workqueue`` threading layer, chosen by :func:`exo_bench.models.machine.numba_runtime.ensure` unless
the user chose one (``NUMBA_THREADING_LAYER``) or numba already started its threads: numba would
otherwise take OpenMP where libgomp is loaded (Pinocchio brings it), and on the shared 2-core
machine OpenMP's statically scheduled, spin-waiting threads made the parallel driver 4 to 150 times
slower than the serial one whenever another process (or Pinocchio's own ``rneaInParallel`` pool)
held a core, while ``workqueue`` was never slower than serial. A parallel driver is entered by one
Python thread at a time (``workqueue`` aborts the process on concurrent parallel launches); a
model called from several threads at once runs the serial driver in the others (:func:`exo_bench.models.machine.numba_runtime.run`).
"""

from __future__ import annotations

import time
from collections import namedtuple
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from exo_bench.models.states.states import RATES, blocks, matrix_names
from exo_bench.matrix_method.closed_forms import factored, planar, transitions as spatial
from exo_bench.models.machine.numba_runtime import JIT, SAMPLES_PER_TASK, ensure
from exo_bench.models.machine.numba_runtime import run  # noqa: F401 - re-exported only for matrix_method/kernels.py (another session's file in this change): it should import run from numba_runtime
from exo_bench.models.machine import numba_cache


# numba's on-disk cache for the matrix family's kernels, keyed on the source of every function a kernel inlines
# (the locator is :mod:`exo_bench.models.machine.numba_cache`, which lists this folder and the files its kernels
# inline in ``KERNEL_SOURCES``): an edit to a closed form in :mod:`exo_bench.matrix_method.closed_forms.planar`
# or ``transitions``, which the kernels inline through ``register_jitable``, recompiles the kernels instead of
# loading stale machine code. tests/test_compiled.py edits an element function in a copy of the package and sees
# the new forces from the compiled kernel.

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


ensure()  # numba's runtime set-up (models/machine/numba_runtime.py), before any kernel of this folder is defined

inline(f for fns in planar.PAIRS.values() for f in fns.values())
inline(f for fns in spatial.PAIRS.values() for f in fns.values())
inline((*planar.GRAVITY.values(), *spatial.GRAVITY.values()))
inline((factored.kappa_2d, factored.forces_2d, factored.kappa_3d, factored.forces_3d))


# ------------------------------------------------------------------ call lists generated from PAIRS
#: The planar elements of eq. (5) in the kernels' layout: matrix m of block b at index 4 b + m.
PLANAR_ELEMENTS = tuple(f for fns in planar.PAIRS.values() for f in fns.values())
#: The spatial elements of eq. (17) in the kernels' layout (blocks phi, psi, l, each A, B, Lambda, D,
#: E, G, H, K: index 8 b + m). ``D`` of block l (index 19) takes the transposed 3D ``H_phi``, not the
#: namespace: the kernels set it after the others.
SPATIAL_ELEMENTS = tuple(f for fns in spatial.PAIRS.values() for f in fns.values())


def _generate(name: str, params: str, lines: list[str], functions: dict[str, Any]) -> Any:
    """A function ``name(params)`` whose body is ``lines``, calling ``functions`` by name, registered
    for the kernels (:func:`~exo_bench.matrix_method.numba_kernels.common.inline`). Its code object
    names this file, so numba's cache is keyed on it and on the modules of ``functions``."""
    src = f"def {name}({params}):\n" + "".join(f"    {line}\n" for line in lines)
    namespace = dict(functions)
    exec(compile(src, __file__, "exec"), namespace)  # noqa: S102 - the call list of PAIRS, generated
    fn = namespace[name]
    fn.__module__ = __name__
    fn.__doc__ = f"Generated from the closed forms' tables: ``{params}``; " + "; ".join(lines)
    inline([fn], always=True)
    return fn


def _element_writer(name: str, op: str, prefix: str, elements: tuple, params: str, args: str, skip: tuple = ()) -> Any:
    fns = {f"{prefix}_{f.__name__}": f for f in elements}
    lines = [f"out[{m}, i, j] {op} {prefix}_{f.__name__}({args})" for m, f in enumerate(elements) if f not in skip]
    return _generate(name, f"out, i, j, {params}", lines, fns)


def _gravity_writer(name: str, op: str, prefix: str, gravity: dict) -> Any:
    fns = {f"{prefix}_{f.__name__}": f for f in gravity.values()}
    lines = [f"out[{b}, i] {op} {prefix}_{f.__name__}(nu_s, li, c, s)" for b, f in enumerate(gravity.values())]
    return _generate(name, "out, i, nu_s, li, c, s", lines, fns)


#: ``out[4 b + m, i, j] = (or +=) planar.PAIRS[b][m](c, li, lj, C, S)`` for every planar element.
set_planar = _element_writer("set_planar", "=", "planar", PLANAR_ELEMENTS, "c, li, lj, C, S", "c, li, lj, C, S")
add_planar = _element_writer("add_planar", "+=", "planar", PLANAR_ELEMENTS, "c, li, lj, C, S", "c, li, lj, C, S")
#: ``out[b, i] = (or +=) planar.GRAVITY[b](nu_s, li, cos, sin)``.
set_planar_gravity = _gravity_writer("set_planar_gravity", "=", "planar", planar.GRAVITY)
add_planar_gravity = _gravity_writer("add_planar_gravity", "+=", "planar", planar.GRAVITY)
#: ``out[8 b + m, i, j] = spatial.PAIRS[b][m](t)`` for every spatial element but ``D_l``.
set_spatial = _element_writer("set_spatial", "=", "spatial", SPATIAL_ELEMENTS, "t", "t", skip=(spatial.d_l,))
#: ``out[b, i] = spatial.GRAVITY[b](nu_s, li, cos psi_i, sin psi_i)``.
set_spatial_gravity = _gravity_writer("set_spatial_gravity", "=", "spatial", spatial.GRAVITY)

#: The namespace ``t`` of :mod:`exo_bench.matrix_method.closed_forms.transitions` for one pair (i, j), as a namedtuple so
#: that the compiled kernels can pass it to the same transition functions: the planar elements
#: (named as :func:`exo_bench.matrix_method.closed_forms.transitions.transition_inputs` names them), their ``*_par`` quotients, the lengths
#: and the cos/sin of ``psi_i``, ``psi_j``.
PLANAR_FIELDS = tuple(f.__name__ for fns in planar.PAIRS.values() for f in fns.values())
#: (Its fields come from the tables: a type checker cannot list them, so it sees ``namedtuple`` as a plain callable.)
_namedtuple: Callable[..., Any] = namedtuple
Transition = _namedtuple("Transition", (*PLANAR_FIELDS, *spatial.QUOTIENTS, "li", "lj", "ci", "si", "cj", "sj"))


def _rate_table(dim: int) -> np.ndarray:
    """:data:`exo_bench.models.states.states.RATES` as numbers for the compiled products: one row per matrix
    of :func:`exo_bench.models.states.states.matrix_names` (in that order), ``(factor, first block, second block)``
    with blocks numbered in the order of ``q`` and ``-1`` where a matrix multiplies a second
    derivative (one block)."""
    bl = blocks(dim)
    rows = []
    for name in matrix_names(dim):
        factor, r = RATES[name]
        rows.append((factor, bl.index(r[0]), bl.index(r[1]) if len(r) == 2 else -1))
    return np.array(rows, dtype=float)


RATES_2D = _rate_table(2)
RATES_3D = _rate_table(3)


def params(c: np.ndarray, nu_s: np.ndarray, g: float) -> np.ndarray:
    """The per-mechanism numbers of a kernel in one C-ordered ``(n, n + 2)`` array (fewer arguments,
    a cheaper call): ``[:, :n]`` the signed coupling ``c_ij``, ``[:, n]`` the gravity coefficients
    ``nu_i s_i``, ``[:, n + 1]`` the gravity ``g`` (every row)."""
    n = c.shape[0]
    p = np.empty((n, n + 2))
    p[:, :n], p[:, n], p[:, n + 1] = c, nu_s, g
    p.flags.writeable = False
    return p


def compile_times(kernels: dict, args: dict) -> dict[str, dict]:
    """Per kernel name, the first call's seconds (compiling, or loading from numba's cache) and
    whether numba's cache served it: ``{name: {"seconds", "cache_hits", "cache_misses"}}``.
    ``kernels[name]`` is a numba dispatcher, ``args[name]`` its arguments."""
    out = {}
    for name, k in kernels.items():
        t0 = time.perf_counter()
        k(*args[name])
        dt = time.perf_counter() - t0
        out[name] = {
            "seconds": dt,
            "cache_hits": int(sum(k.stats.cache_hits.values())),
            "cache_misses": int(sum(k.stats.cache_misses.values())),
        }
    return out


# ------------------------------------------------------------------ drivers generated from one template
_SERIAL_DRIVER = """\
def {name}(p, {extra}q, qd, qdd, o):
    {samples}(p, {extra}q, qd, qdd, o, 0, q.shape[0] // ({dim} * p.shape[0]){tail})
"""
_PARALLEL_DRIVER = """\
def {name}_parallel(p, {extra}q, qd, qdd, o):
    S = q.shape[0] // ({dim} * p.shape[0])
    for b in prange((S + SAMPLES_PER_TASK - 1) // SAMPLES_PER_TASK):
        {samples}(p, {extra}q, qd, qdd, o, b * SAMPLES_PER_TASK, min(S, (b + 1) * SAMPLES_PER_TASK){tail})
"""


def drivers(
    module: str,
    prefix: str,
    method: str,
    samples: dict[int, Any],
    extra: tuple[str, ...] = (),
    dim_argument: bool = False,
) -> dict[int, tuple[Any, Any]]:
    """``{dim: (serial driver, parallel driver)}`` of a kernel module, from one template: the serial
    driver runs every sample of the flat states through ``samples[dim](p, *extra, q, qd, qdd, o, start,
    stop[, dim])``, the parallel one runs tasks of :data:`SAMPLES_PER_TASK` samples over numba's threads.

    The drivers are named ``<prefix>_<dim>d`` and ``<prefix>_<dim>d_parallel``, compiled with the
    file name of ``module`` (so numba's cache, and its :mod:`~exo_bench.matrix_method.numba_kernels.common`
    locator, key them on that kernel file) and set as attributes of it."""
    import sys

    from numba import prange

    mod = sys.modules[module]
    if mod.__file__ is None:
        raise ValueError(f"{module} has no source file: numba could not key its drivers' cache on it")
    args = "".join(f"{a}, " for a in extra)
    out = {}
    for dim, fn in samples.items():
        name = f"{prefix}_{dim}d"
        fields = dict(name=name, extra=args, samples=fn.__name__, dim=dim, tail=f", {dim}" if dim_argument else "")
        namespace = {fn.__name__: fn, "prange": prange, "SAMPLES_PER_TASK": SAMPLES_PER_TASK}
        exec(
            compile(_SERIAL_DRIVER.format(**fields) + _PARALLEL_DRIVER.format(**fields), mod.__file__, "exec"),
            namespace,
        )  # noqa: S102
        pair = []
        for fname, doc, parallel in (
            (
                name,
                f"Method ``{method}``, {'planar' if dim == 2 else 'spatial'}: every sample "
                "of the flat states, in turn, into ``o``.",
                False,
            ),
            (
                f"{name}_parallel",
                f":func:`{name}` with tasks of :data:`exo_bench.matrix_method."
                "numba_kernels.common.SAMPLES_PER_TASK` samples over numba's threads.",
                True,
            ),
        ):
            f = namespace[fname]
            f.__module__, f.__qualname__, f.__doc__ = module, fname, doc
            kernel = njit(parallel=True, **JIT)(f) if parallel else njit(**JIT)(f)
            setattr(mod, fname, kernel)
            pair.append(kernel)
        out[dim] = (pair[0], pair[1])
    return out
