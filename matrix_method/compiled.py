"""Compiled (numba) kernels of the matrix family: what they share.

The kernels themselves, one algorithm per file:

* :mod:`matrix_method.compiled_factored` (method ``matrix-factored``): eq. (5)/(17) in factored
  form, no matrix formed (the derivation is in :func:`matrix_method.numeric.inverse_dynamics`);
* :mod:`matrix_method.compiled_matrix` (method ``matrix``): every matrix of eq. (5)/(17) formed
  from the closed forms of :mod:`matrix_method.planar` and :mod:`matrix_method.spatial`, then the
  products with the rates of :data:`models.equation_form.RATES`;
* :mod:`matrix_method.compiled_recurrence` (method ``recurrence``): the planar matrices grown link
  by link by eqs. (22)-(26), then the same transitions and products.

The pure-numpy kernels (:mod:`matrix_method.numeric`, :mod:`matrix_method.recurrence`) stay the
reference implementation; tests/test_compiled.py holds these to them at 1e-14 relative.

**One kernel, one sample or a batch.** Each algorithm is a per-sample function, a block function
that runs it over samples ``start .. stop - 1`` with its scratch allocated once, and two drivers
``kernel(*args, q, qd, qdd, o)`` that write the forces into ``o``; states and forces are flat,
C-ordered ``(samples * dof,)`` float64 arrays (a ``(dof,)`` sample is already one, a
``(samples, dof)`` batch is its ``reshape(-1)``, a view): one signature per kernel. The serial
driver runs one block; for batches of at least :data:`PARALLEL_MIN_SAMPLES` samples the parallel
driver runs blocks of :data:`BLOCK` samples over numba's threads (``prange``). Writing into a
given ``o`` (no array returned) leaves a one-sample call with numba's dispatch and the arithmetic
only (returning a new array cost about as much as the arithmetic of exo5-3d): the caller may
preallocate it (``inverse_dynamics(..., out=)``).

**Closed forms written once.** The compiled ``matrix`` and ``recurrence`` kernels call the very
functions of :mod:`matrix_method.planar` and :mod:`matrix_method.spatial` (registered here with
``numba.extending.register_jitable``, which leaves them plain Python functions for numpy and
sympy); the transitions take their namespace ``t`` as a namedtuple (:data:`Transition`).

**Compile once per machine.** ``cache=True`` writes the machine code beside this package
(``__pycache__``, or numba's user-wide cache folder where that is not writable), so a second
process loads it instead of compiling. The first call of each kernel in a fresh cache compiles it
(1 to 10 s each on the 2-core machine, the ``compile`` table of reports/scaling.md, measured by
:func:`compile_times`). numba's cache is invalidated when the
kernel's own file changes, not when a closed form in ``planar.py``/``spatial.py`` does: after
editing those, delete ``matrix_method/__pycache__/*.nbi``/``*.nbc`` (the tests would catch the
stale kernel: they hold it to the numpy reference).

**Threads.** (``matrix-factored``'s batches run :mod:`matrix_method.compiled_simd` instead, on a
Python thread pool that never enters numba's threading layer.) The parallel drivers run on numba's ``workqueue`` threading layer, set here unless
the user chose one (``NUMBA_THREADING_LAYER``) or numba already started its threads: numba would
otherwise take OpenMP where libgomp is loaded (Pinocchio brings it), and on the shared 2-core
machine OpenMP's statically scheduled, spin-waiting threads made the parallel driver 4 to 150 times
slower than the serial one whenever another process (or Pinocchio's own ``rneaInParallel`` pool)
held a core, while ``workqueue`` was never slower than serial. A parallel driver is entered by one
Python thread at a time (``workqueue`` aborts the process on concurrent parallel launches); a
model called from several threads at once runs the serial driver in the others (:func:`run`).
"""

from __future__ import annotations

import time
from collections import namedtuple

import numpy as np
from numba import njit  # noqa: F401 - re-exported for the kernel modules
from numba.extending import register_jitable

from exo_bench.matrix_method import planar, spatial
from exo_bench.models import equation_form
from exo_bench.models.numba_threads import (  # noqa: F401 - shared with models.newton_euler, re-exported
    BLOCK, JIT, PARALLEL_MIN_SAMPLES, THREADING_LAYER, _PARALLEL, _threading_layer, run)

for _fns in (*planar.PAIRS.values(), *spatial.PAIRS.values()):
    for _f in _fns.values():
        register_jitable(_f)
for _f in (*planar.GRAVITY.values(), *spatial.GRAVITY.values()):
    register_jitable(_f)

#: The namespace ``t`` of :mod:`matrix_method.spatial` for one pair (i, j), as a namedtuple so
#: that the compiled kernels can pass it to the same transition functions: the planar elements
#: (named as :func:`spatial.transition_inputs` names them), their ``*_par`` quotients, the lengths
#: and the cos/sin of ``psi_i``, ``psi_j``.
PLANAR_FIELDS = tuple(f.__name__ for fns in planar.PAIRS.values() for f in fns.values())
Transition = namedtuple("Transition", (*PLANAR_FIELDS, *spatial.QUOTIENTS, "li", "lj", "ci", "si", "cj", "sj"))


def _rate_table(dim: int) -> np.ndarray:
    """:data:`models.equation_form.RATES` as numbers for the compiled products: one row per matrix
    of :func:`equation_form.matrix_names` (in that order), ``(factor, first block, second block)``
    with blocks numbered in the order of ``q`` and ``-1`` where a matrix multiplies a second
    derivative (one block)."""
    bl = equation_form.blocks(dim)
    rows = []
    for name in equation_form.matrix_names(dim):
        factor, r = equation_form.RATES[name]
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
        out[name] = {"seconds": dt, "cache_hits": int(sum(k.stats.cache_hits.values())),
                     "cache_misses": int(sum(k.stats.cache_misses.values()))}
    return out

