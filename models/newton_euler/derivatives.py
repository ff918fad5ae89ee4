"""Analytic derivatives of inverse dynamics through the Newton-Euler passes: ``dtau/dq``, ``dtau/dqd`` and
``M = dtau/dqdd``, O(1) work per output block, for trees with branch signs, 2D and 3D.

**How to call.** Prepare once per mechanism, call per batch (Pinocchio's model/data split)::

    from exo_bench.models.newton_euler.derivatives import prepare_inverse_derivatives
    d = prepare_inverse_derivatives(mechanism)              # fixed data: tree, signs, mu, g, dim, scratch
    dtau_dq, dtau_dqd, M = d(q, qd, qdd)                    # (S, dof) each -> (S, dof, dof) each
    d(q, qd, qdd, out=(a, b, c))                            # into preallocated (S, dof, dof) arrays
    d(q1, qd1, qdd1)                                        # one (dof,) sample -> (dof, dof) each
    d(q, qd, qdd, kernel="numpy")                           # "numpy" | "numba" | "simd" | "auto"

``J[s, i, j] = d tau_i / d x_j`` in block order ``[phi..., psi..., l...]``. The states must be C-contiguous
float64 ndarrays of one shape, ``(S, dof)`` or ``(dof,)``; ``out`` a tuple of three writable C-contiguous
float64 arrays of the result's shape, apart from each other and from the states. Those are checked at
every call (memory safety: a ValueError naming the field, the expected and the actual value); the
VALUES are not (NaN in, NaN out): the provider above this (``model.derivatives``) validates them and
refuses singular states. :data:`KERNELS` lists the kernels; ``"auto"`` takes the per-sample compiled
kernel for one sample and the batched one otherwise.

**The derivation.** Coordinates are absolute: rod ``i`` has its own ``q_i`` (``(phi, l)`` or ``(phi,
psi, l)``) and ``r_i = s_i l_i u_i(q_i)`` depends on ``q_i`` only. With the constant coupling ``mu``
(:func:`exo_bench.models.mechanism.aggregates.coupling`) ``T = 1/2 sum_ij mu_ij r_i'.r_j'``, so the rod force that
the backward pass accumulates is ``F_i = sum_j mu_ij a_j + nu_i g up`` with ``a_j = r_j'' = J_j qdd_j +
J_j' qd_j`` (a function of ``q_j, qd_j, qdd_j`` only) and ``tau_i = J_i(q_i)^T F_i``. Differentiating::

    dtau_i/dq_j  = delta_ij d(J_i^T F)/dq_i |_{F = F_i} + mu_ij J_i^T da_j/dq_j,
    dtau_i/dqd_j = mu_ij J_i^T da_j/dqd_j,          M_ij = mu_ij J_i^T J_j,

the signs ``s_i s_j`` inside ``J`` and ``a``. Per rod, the ``dim x dim`` blocks ``da_j/dq_j``,
``da_j/dqd_j``, ``J_j`` and ``d(J_i^T F)/dq_i`` come from the rod elements
(:mod:`exo_bench.models.newton_euler.derivative_elements`, which reuses
:mod:`exo_bench.models.mechanism.rod_elements`); ``F_i`` from the two passes; every output block is then
``mu_ij J_i^T Y_j``, ``3 dim^2`` dot products of length ``dim``. ``mu_ij = 0`` unless ``i`` and ``j`` lie
on one root path: a branched tree's blocks off those paths are zero.

**Why this structured form, not forward mode through the passes.** Forward mode with one direction
per coordinate re-runs the O(n) passes ``dim n`` times (for ``dq`` and again for ``dqd``): each
direction ``e_j`` changes ``a_j`` only, and the passes then spread ``da_j`` over the tree to give
``dF_i = mu_ij da_j`` by sums along root paths, the same numbers as one column of ``mu``, read here
from the matrix instead of recomputed. The structured form writes each output entry once from
``dim`` multiply-adds and a factor ``mu_ij`` (O(n^2), the size of the output, with no pass per
direction), its inner loop over ``j`` reads contiguous per-link rows and vectorises, and ``M`` comes
with it at ``1/3`` of the work. Forward mode through the passes would cost 2-3x the flops for the same
output and carry a dual number through every element.

The kernels: the numpy reference below (vectorised over samples; runs on complex
arrays for complex-step checks), :mod:`.derivatives_compiled` (numba, per sample, and threads over
samples for batches), :mod:`.derivatives_simd` (numba, blocks of samples across SIMD lanes).

**The numpy reference**, vectorised over samples.

The algorithm (its derivation and why it is structured this way: :mod:`exo_bench.models.newton_euler.derivatives`):
per sample, the two passes give each rod's force ``F_i`` (:func:`exo_bench.models.newton_euler.passes.rod_forces`);
per rod the signed columns ``Y_j = s_j [d a_j/d q_j, d a_j/d qd_j, J_j]`` and the diagonal term ``s_i
d(J_i^T F)/d q_i`` (:mod:`exo_bench.models.newton_euler.derivative_elements`); then every block
``mu_ij J_i^T Y_j`` at once by ``einsum``.

Runs on complex arrays too (arithmetic, ``cos`` and ``sin`` only): tests/test_derivatives_analytic.py
differentiates it by complex steps. Arrays are batch-first: ``(S, dof)`` in, ``(S, dof, dof)`` out in
block order ``[phi..., psi..., l...]``.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.newton_euler import derivative_elements as de
from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.passes import Tree, prepare_tree
from exo_bench.models.runtime.prepared import ResultPool


def _columns(parts, dim: int, sign: np.ndarray) -> np.ndarray:
    """Flat per-rod columns (column-major tuples of :mod:`.derivative_elements`, each ``(n, S)``) as
    ``(n, dim, dim, S)`` ``[link, component, column, sample]``, times the links' signs."""
    n, S = sign.shape[0], np.shape(parts[0])[-1]
    a = np.stack([np.broadcast_to(p, (n, S)) for p in parts]).reshape(dim, dim, n, S)
    return np.transpose(a, (2, 1, 0, 3)) * sign[:, None, None, None]


def rod_columns(tree: Tree, dim: int, g: float, q, qd, qdd):
    """Per rod, signed, ``(n, dim, dim, S)`` each: ``J_j``, ``d a_j/d q_j``, ``d a_j/d qd_j`` (``a_j = r_j''``),
    and ``s_i d(J_i^T F_i)/d q_i`` (``[link, row, column, sample]``), with ``F`` from the two passes."""
    n = tree.parent.shape[0]
    trig = passes._trig(dim, n, q)
    F = passes.rod_forces(tree, dim, g, passes.rod_accelerations(tree, dim, q, qd, qdd, trig))
    cf, sf, cp, sp = trig
    X, Xd, Xdd = q.T, qd.T, qdd.T
    l, s = X[(dim - 1) * n :], tree.sign
    if dim == 2:
        w, ld, wdd, ldd = Xd[:n], Xd[n:], Xdd[:n], Xdd[n:]
        J = de.jacobian_2d(cf, sf, l)
        Aq = de.acceleration_by_q_2d(cf, sf, l, w, ld, wdd, ldd)
        Ar = de.acceleration_by_rates_2d(cf, sf, l, w, ld)
        P = de.projection_by_q_2d(cf, sf, l, F[:, 0], F[:, 1])
    else:
        w, v, ld = Xd[:n], Xd[n : 2 * n], Xd[2 * n :]
        J = de.jacobian_3d(cf, sf, cp, sp, l)
        Aq = de.acceleration_by_q_3d(cf, sf, cp, sp, l, w, v, ld, Xdd[:n], Xdd[n : 2 * n], Xdd[2 * n :])
        Ar = de.acceleration_by_rates_3d(cf, sf, cp, sp, l, w, v, ld)
        P = de.projection_by_q_3d(cf, sf, cp, sp, l, F[:, 0], F[:, 1], F[:, 2])
    return tuple(_columns(x, dim, s) for x in (J, Aq, Ar, P))


def inverse_derivatives(tree: Tree, mu: np.ndarray, dim: int, g: float, q, qd, qdd):
    """``(dtau_dq, dtau_dqd, M)``, ``(S, dof, dof)`` each, of inverse dynamics at ``(S, dof)`` states
    (real or complex): ``dtau_i/dq_j = delta_ij s_i d(J_i^T F_i)/dq_i + mu_ij J_i^T s_j da_j/dq_j``,
    ``dtau_i/dqd_j = mu_ij J_i^T s_j da_j/dqd_j``, ``M_ij = mu_ij J_i^T J_j``."""
    n = tree.parent.shape[0]
    S, dof = q.shape
    J, Aq, Ar, P = rod_columns(tree, dim, g, q, qd, qdd)

    def blocks(Y):
        return np.einsum("ij,ieas,jebs->saibj", mu, J, Y).reshape(S, dof, dof)

    dq = blocks(Aq)
    link = np.arange(n)
    for a in range(dim):
        for b in range(dim):
            dq[:, a * n + link, b * n + link] += P[:, a, b].T
    return dq, blocks(Ar), blocks(J)


#: The kernels ``InverseDerivatives.__call__`` takes (``kernel=``), each the name of the method of
#: :class:`InverseDerivatives` that runs a batch (a table: no branch on a kernel's name).
KERNELS = {"numpy": "_numpy", "numba": "_numba", "simd": "_simd", "auto": "_auto"}
#: The options under which one ``(dof,)`` sample runs the lean one-sample entry (:meth:`InverseDerivatives.one`).
LEAN = frozenset({"numba", "auto"})
#: The names of the three outputs, in order (``out[k]`` is named ``out[k] (NAME)`` in errors).
OUTPUTS = ("dtau_dq", "dtau_dqd", "M")
_SOURCE = "inverse-dynamics derivatives"
_F8 = np.dtype(np.float64)
#: ``kernel="auto"``: batches of mechanisms of fewer links run the SIMD kernel, larger ones the
#: per-sample kernel (whose loop over the column links vectorises and writes contiguous rows). Per
#: sample, one thread, one process, the shared 2-core machine at load 11: exo5-3d (512 samples) simd
#: 2.3-2.6 us against numba 2.7-2.8; a 3D tree of 9 links 6-24 against 30-32; a 3D chain of 10 a tie
#: (33 us, both bound by writing 22 kB per sample); chain of 20 (64 samples) 43-52 against 22-25.
SIMD_BELOW_LINKS = 10
#: numba_runtime's threshold of a parallel batch, in samples (its value; importing it would import numba).
PARALLEL_MIN_SAMPLES = 4096
#: A batch of at least this many output entries runs on numba's threads.
PARALLEL_MIN_ENTRIES = 2**18
#: Results of at least this many bytes are recycled once dropped (:class:`InverseDerivatives`): glibc's
#: initial mmap threshold, above which a result may come from a fresh mapping (result_pool's own default,
#: 4 MiB, is for results of inverse dynamics, of which a batch is ``dof`` times smaller).
RECYCLE_MIN_BYTES = 1 << 17


def _state_problem(name: str, a, dof: int) -> str | None:
    """What is wrong with one state array (type, dtype, shape, layout), or None."""
    if not isinstance(a, np.ndarray):
        return f"field '{name}': expected a numpy.ndarray of float64, got {type(a).__name__}"
    if a.dtype != np.float64:
        return f"field '{name}': expected dtype float64, got {a.dtype}"
    if a.ndim not in (1, 2) or a.shape[-1] != dof:
        return f"field '{name}': expected shape ({dof},) or (samples, {dof}), got {a.shape}"
    if not a.flags.c_contiguous:
        return f"field '{name}': expected a C-contiguous array, got strides {a.strides}"
    return None


def check_states(q, qd, qdd, dof: int) -> tuple[int, ...]:
    """The common shape of the three state arrays, ``(dof,)`` or ``(S, dof)``; else a ValueError naming
    the field, the expected and the actual value."""
    for name, a in (("q", q), ("qd", qd), ("qdd", qdd)):
        problem = _state_problem(name, a, dof)
        if problem:
            raise ValueError(f"{_SOURCE}: {problem}")
    for name, a in (("qd", qd), ("qdd", qdd)):
        if a.shape != q.shape:
            raise ValueError(f"{_SOURCE}: field '{name}': expected shape {q.shape} (as q), got {a.shape}")
    return q.shape


def check_out(out, shape: tuple[int, ...], states: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
    """``out`` as three arrays of ``shape``, writable, C-contiguous float64, apart from each other and from
    the states; else a ValueError naming ``out[k]``, the expected and the actual value."""
    if not isinstance(out, (tuple, list)) or len(out) != 3:
        got = f"{type(out).__name__} of {len(out)}" if isinstance(out, (tuple, list)) else type(out).__name__
        raise ValueError(f"{_SOURCE}: field 'out': expected a tuple of 3 arrays {OUTPUTS}, got {got}")
    for k, o in enumerate(out):
        field = f"field 'out[{k}]' ({OUTPUTS[k]})"
        if not isinstance(o, np.ndarray):
            raise ValueError(f"{_SOURCE}: {field}: expected a numpy.ndarray of float64, got {type(o).__name__}")
        if o.dtype != np.float64:
            raise ValueError(f"{_SOURCE}: {field}: expected dtype float64, got {o.dtype}")
        if o.shape != shape:
            raise ValueError(f"{_SOURCE}: {field}: expected shape {shape}, got {o.shape}")
        if not o.flags.c_contiguous or not o.flags.writeable:
            raise ValueError(
                f"{_SOURCE}: {field}: expected a writable C-contiguous array, got "
                f"{'read-only' if not o.flags.writeable else f'strides {o.strides}'}"
            )
        others = [("q", states[0]), ("qd", states[1]), ("qdd", states[2])]
        others += [(f"out[{m}]", out[m]) for m in range(k)]
        for other, a in others:
            if np.may_share_memory(o, a):
                raise ValueError(f"{_SOURCE}: {field}: expected memory apart from {other}, got an overlap")
    return tuple(out)


class InverseDerivatives:
    """The derivatives of one mechanism's inverse dynamics (module docstring), prepared once: the
    tree's numbers (:func:`exo_bench.models.newton_euler.passes.prepare_tree`), the coupling ``mu``,
    ``g``, ``dim``, and each thread's scratch of the compiled kernels. Call it (``__call__``)."""

    def __init__(self, mechanism: Mechanism):
        self.mechanism = mechanism
        self.tree = prepare_tree(mechanism)
        self.table = self.tree.table()
        self.mu = np.ascontiguousarray(coupling(mechanism), dtype=np.float64)
        self.g, self.dim = float(mechanism.g), int(mechanism.dim)
        self.nlinks, self.dof = int(mechanism.nlinks), int(mechanism.dof)
        self._local = threading.local()
        self._entry: tuple | None = None
        #: The shapes of one sample's states and outputs, ``(dof,)`` and ``(dof, dof)``.
        self._shapes = ((self.dof,), (self.dof, self.dof))
        self._simd_scratch: Any = None  # the SIMD kernel's driver, kernel, parameters and scratch (_simd_prepare)
        #: New batched results, recycled once dropped (:mod:`exo_bench.models.runtime.prepared`): a fresh
        #: ``(S, dof, dof)`` array may be a new mapping whose pages the OS zeroes on first touch; chain 100
        #: 3D, 27 samples: 0.69 ms per sample with new results, 0.37 with ``out=``; exo5-3d, 256 samples
        #: (460 kB each): 3.6 us against 1.6 (193 page faults a call), so from :data:`RECYCLE_MIN_BYTES`.
        #: Six: the three results of two calls (a loop holds the previous ones during the next call).
        self._results = ResultPool(keep=2 * len(OUTPUTS), min_bytes=RECYCLE_MIN_BYTES)

    def __repr__(self) -> str:
        return f"<InverseDerivatives of {self.mechanism.name!r}: {self.dof} dof, {self.dim}D>"

    def __call__(self, q, qd, qdd, out=None, kernel: str = "auto"):
        """``(dtau_dq, dtau_dqd, M)`` at the states (module docstring): ``(S, dof, dof)`` each, or
        ``(dof, dof)`` for one ``(dof,)`` sample; into ``out`` if given (and returned)."""
        if kernel in LEAN and type(q) is np.ndarray and q.ndim == 1:
            return self.one(q, qd, qdd, out)
        return self._checked(q, qd, qdd, out, kernel)

    def _checked(self, q, qd, qdd, out, kernel: str):
        """The general path: every check by :func:`check_states` and :func:`check_out`, then the kernel."""
        shape = check_states(q, qd, qdd, self.dof)
        run = KERNELS.get(kernel) if isinstance(kernel, str) else None
        if run is None:
            raise ValueError(f"{_SOURCE}: option 'kernel': expected one of {tuple(KERNELS)}, got {kernel!r}")
        oshape = (*shape, self.dof)
        if out is None:
            out = tuple(self._results.empty(oshape) for _ in OUTPUTS)
        else:
            out = check_out(out, oshape, (q, qd, qdd))
        if len(shape) == 1:
            getattr(self, run)(q[None], qd[None], qdd[None], tuple(o[None] for o in out))
        elif shape[0]:
            getattr(self, run)(q, qd, qdd, out)
        return out

    def one(self, q, qd, qdd, out=None):
        """One ``(dof,)`` sample by the compiled per-sample kernel, ``(dof, dof)`` each: the lean entry.
        No check in Python: numba's dispatcher matches the arguments' types in C (ndarray, float64,
        number of dimensions, C-contiguous, ``out`` writable) against the one signature it compiled and
        may not compile another (:meth:`_one_entry`), and the kernel tests the lengths, the shapes and the
        overlap of ``out`` with the states. Anything either refuses goes to the checked path, which names
        the field (or runs what only the lean entry refused, e.g. read-only states)."""
        if out is None:
            mshape = self._shapes[1]
            out = (np.empty(mshape), np.empty(mshape), np.empty(mshape))
        elif type(out) is not tuple or len(out) != 3:
            return self._checked(q, qd, qdd, out, "numba")
        entry, n, g, dim = self._entry or self._one_entry()
        ws = getattr(self._local, "ws", None)
        if ws is None:
            ws = self._workspace()
        try:
            if entry(ws, n, g, dim, q, qd, qdd, out[0], out[1], out[2]) == 0:
                return out
        except TypeError:  # a type the dispatcher has no signature for
            pass
        return self._checked(q, qd, qdd, out, "numba")  # names what is wrong

    def _one_entry(self):
        """numba's dispatcher of the one-sample entry (``derivatives_one``), compiled (or loaded from
        numba's cache) for exactly these types and then closed to any other (``disable_compile``: a call
        with other types raises TypeError in the dispatcher's C type match, before any work), and its
        scalar arguments ``(n, g, dim)``; made at the first call. Under ``NUMBA_DISABLE_JIT`` the Python
        function (numpy then checks the indexing)."""
        from exo_bench.models.newton_euler import derivatives_compiled as dc

        v, m = np.empty(self.dof), np.empty((self.dof, self.dof))
        lead = (self.nlinks, self.g, self.dim)
        entry = dc.derivatives_one
        if getattr(entry, "_can_compile", False):  # the first in this process; the signature is the same for all
            import numba

            entry.compile(tuple(numba.typeof(a) for a in (self._workspace(), *lead, v, v, v, m, m, m)))
            entry.disable_compile()
        self._entry = (entry, *lead)
        return self._entry

    def _workspace(self):
        """This thread's packed workspace of the one-sample entry (made at its first call, then reused)."""
        from exo_bench.models.newton_euler import derivatives_compiled as dc

        ws = self._local.ws = dc.workspace(self.table, self.mu, self.dim)
        return ws

    # ------------------------------------------------------------------ the kernels (KERNELS), on a batch
    def _numpy(self, q, qd, qdd, out) -> None:
        res = inverse_derivatives(self.tree, self.mu, self.dim, self.g, q, qd, qdd)
        for o, r in zip(out, res):
            o[...] = r

    def _simd(self, q, qd, qdd, out) -> None:
        run_simd, kernel, params, scratch = self._simd_scratch or self._simd_prepare()
        flat = (q.reshape(-1), qd.reshape(-1), qdd.reshape(-1))
        run_simd(kernel, params, *flat, tuple(out), q.shape[0], scratch=scratch)

    def _simd_prepare(self) -> tuple:
        """The SIMD kernel's driver, kernel, parameters and ThreadScratch, made at its first call (the
        imports and the tuple once, not per call: a few us of a batch's fixed cost)."""
        from exo_bench.models.machine.simd_blocks import ThreadScratch
        from exo_bench.models.machine.simd_blocks import run as run_simd
        from exo_bench.models.newton_euler import derivatives_simd as ds

        scratch = ThreadScratch(ds.scratch, self.nlinks, self.dim)
        self._simd_scratch = (run_simd, ds.simd_derivatives, (self.table, self.mu, self.g, self.dim), scratch)
        return self._simd_scratch

    def _numba(self, q, qd, qdd, out) -> None:
        from exo_bench.models.machine.numba_runtime import run
        from exo_bench.models.newton_euler import derivatives_compiled as dc
        from exo_bench.models.newton_euler.derivatives_compiled import streams

        args = (self.table, self.mu, self.g, self.dim, q, qd, qdd, *out, streams(out, self.dof))
        run(dc.derivatives_serial, dc.derivatives_parallel, args, self._parallel_samples(q.shape[0]))

    def _auto(self, q, qd, qdd, out) -> None:
        (self._simd if self.auto_simd() is not None else self._numba)(q, qd, qdd, out)

    def auto_simd(self) -> tuple | None:
        """The SIMD kernel's driver, kernel, parameters and scratch (:meth:`_simd_prepare`) where
        ``kernel="auto"`` runs it on a batch (fewer than :data:`SIMD_BELOW_LINKS` links), else None."""
        if self.nlinks >= SIMD_BELOW_LINKS:
            return None
        return self._simd_scratch or self._simd_prepare()

    def _parallel_samples(self, samples: int) -> int:
        """``samples`` in units of numba_runtime's threshold: the batch runs on threads from
        :data:`PARALLEL_MIN_ENTRIES` output entries on."""
        return samples * 3 * self.dof * self.dof * PARALLEL_MIN_SAMPLES // PARALLEL_MIN_ENTRIES


def prepare_inverse_derivatives(mechanism: Mechanism) -> InverseDerivatives:
    """The prepared derivatives of ``mechanism``'s inverse dynamics (:class:`InverseDerivatives`)."""
    return InverseDerivatives(mechanism)
