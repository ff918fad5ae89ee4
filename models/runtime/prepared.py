"""The prepared model: a method's per-mechanism work done once, then cheap calls through its kernels.

Like Pinocchio's ``Model``/``Data`` split, :class:`PreparedModel` holds what is fixed for a
mechanism (aggregates, coupling signs, index arrays, lambdified functions, the Pinocchio model);
its calls take states and return forces.

**One way through each public call.** The public calls are defined here once; a method supplies
kernels (objects of :mod:`exo_bench.models.runtime.prepared`, listed in its MethodSpec, whose entries the calls
run) or implements :meth:`PreparedModel._inverse_dynamics` on validated ``(samples, dof)`` float arrays; it
never overrides a public call. A call validates once, at the edge, then runs the method's kernel:

1. the array gate (:mod:`exo_bench.models.states.array_gate`): every input and ``out`` that reaches a compiled
   kernel is a base-class, C-ordered, aligned float64 ndarray of exactly the shape the kernel indexes;
   with ``check=True`` any other input is converted, with ``check=False`` it is refused, and an ``out``
   that is not exactly right is refused with a ValueError naming ``out`` either way (``check=False``
   skips the values, never memory safety);
2. with ``check=True`` the values: finiteness, rod lengths >= 0, the force bound (one compiled pass,
   :func:`~exo_bench.models.states.states.checked_states`), and for forward dynamics the refusal of singular
   configurations (:meth:`PreparedModel.check_regular`);
3. the kernel.

**One sample, fast.** A kernel may supply a compiled validate-and-compute entry of one sample
(:class:`~exo_bench.models.runtime.prepared.Entries` ``inverse_fast``, ``forward_fast``: steps 1 to 3 in one numba
call that answers 0 or a problem's code). The public call checks in Python only what numba's unboxing
trusts (the arrays are base-class ndarrays, 1-D, float64; ``out`` writable) and calls it; any other
answer runs the path above, which names the problem.

:meth:`PreparedModel.mass_matrix` and :meth:`PreparedModel.bias_forces` are native where a method
overrides ``_mass_matrix``/``_bias_forces`` (``native_terms`` says which) and are otherwise derived
from inverse dynamics, which is linear in ``qdd``: ``h = ID(q, qd, 0)`` and ``M e_k = ID(q, 0, e_k) -
ID(q, 0, 0)`` (:func:`~exo_bench.models.runtime.prepared.terms_from_inverse_dynamics`).

**Chunks.** A batch is evaluated :attr:`PreparedModel.chunk_samples` samples at a time into a
preallocated result, so that a batch of any length needs the inputs, the result and a fixed working
set (one chunk's temporaries): 10^6 samples take no more scratch memory than one chunk
(bench/test_memory.py). A result of 4 MiB or more reuses the memory of one returned before, once nothing
refers to that one any more (:mod:`exo_bench.models.runtime.prepared`).

**Threads and processes.** A prepared model holds no mutable state shared between calls (a one-sample
entry's scratch is on the stack of its call), so one model can serve several threads. It pickles by
reconstruction: the pickle holds the mechanism, the method's name and its options, and unpickling
prepares the model again in the receiving process (for ``lagrange`` that derives the equations again,
within the same budget).

**Derived terms.** What every prepared model derives from its inverse dynamics: the mass matrix and the bias forces
(:func:`terms_from_inverse_dynamics`, one batched call), and forward dynamics by an equilibrated Cholesky
solve of ``M qdd = tau - h`` (:func:`cholesky_solve`, never NaN). Used by
:class:`~exo_bench.models.runtime.prepared.PreparedModel` where a method has no terms of its own.

**The result pool.** Result arrays recycled once their caller has dropped them: a prepared model's free list.

A batched call without ``out=`` returns a new array. glibc serves a request above its mmap threshold
(dynamic, at most 32 MiB) with a fresh mapping, which it unmaps again on ``free``, so every such call
pays the OS for zeroing the result's pages on first touch, in the kernel's threads. Measured on
``newton-euler``, 3D chain of 1000 links, 1398 samples (the full sweep's row: a 33.5 MB result), two
threads: 19.2-24.0 ms per call with a new result (530 page faults each, ``getrusage``) against
12.6-14.1 ms with ``out=``, the rest of the call unchanged. Whether glibc maps afresh or reuses its
heap depends on what the process allocated before, so the same call measured 12.5 ms in another
script: the cost was noise in the sweep as well as a cost.

:class:`ResultPool` keeps the last :data:`KEEP` results of at least :data:`MIN_BYTES` that it handed
out, and hands one out again when nothing outside the pool refers to it any more (its reference count
is the pool's own, :func:`_refs`): the caller's result is never written after it was returned, and
a view, a ``memoryview`` or a ``ctypes`` pointer object of it keeps it from reuse like the array itself.
Two alternate in a loop ``tau = model.inverse_dynamics(...)``, which still holds the previous result
while the next call runs. The cost is memory: up to :data:`KEEP` results stay allocated after the
caller dropped them, until the model is released. Reference counts cannot tell this in a
free-threaded build (deferred counts), so there every call allocates (:data:`RECYCLES`).

**Kernels**: the code a method runs, each an object listed in the method's
:class:`~exo_bench.api.methods.MethodSpec` (and its prepared-model class's ``kernels``).

A :class:`Kernel` states what it computes (the public calls it serves), for which shapes (one sample,
a batch), its cost (against the method's cost formulas, :mod:`exo_bench.api.cost_formulas`) and its
threading; :attr:`Kernel.load` binds it to one prepared model (its coefficients, its compiled
entry points), giving :class:`Entries`. The option ``kernel`` of a method names a group of its
kernels (``kernel="numba"`` runs matrix-factored's per-sample, SIMD and lean kernels); the public
calls are :class:`~exo_bench.models.runtime.prepared.PreparedModel`'s, which run the entries: a method never
overrides them. Adding a kernel is one module (its code and a ``load``) and one entry in the tuple of
its method's kernels (docs/add-a-kernel.md).
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np
from exo_bench.models.machine.memory import CHUNK_BYTES, check_batch, chunks, default_chunk_samples
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.singularity import SingularConfigurationError, singular_reasons
from exo_bench.models.runtime import external_forces
from exo_bench.models.runtime.conditioning import (
    CouplingCondition,
    check_conditioning,
    check_finite,
    coupling_condition,
)
from exo_bench.models.states.array_gate import apart, as_out
from exo_bench.models.states.array_gate import as_states as gate_states
from exo_bench.models.states.states import checked_states, is_one_sample

#: The shapes a kernel takes: one sample given as 1-D arrays, or a batch ``(samples, dof)``.
ONE_SAMPLE = "one sample"
BATCH = "batch"

#: numba's own memory on the first call (LLVM, the threading layer): the VmHWM growth of a first
#: batched call on exo5-3d is 58 MB when the machine code loads from numba's on-disk cache and
#: 121 MB when it compiles (an empty cache); the larger, rounded up, so that the estimate does not
#: depend on the state of the cache. Counted once in the setup of a method whose kernels are compiled.
NUMBA_BYTES = 128 * 2**20


@dataclass(slots=True)
class Entries:
    """What the kernels of one option supply to a prepared model (None: not supplied, the base
    class's generic path runs). Arrays are float64, C-ordered; ``out`` is written and returned.

    * ``inverse_fast(q, qd, qdd, out, check) -> int``, ``forward_fast(q, qd, tau, out, check) -> int``: one
      sample in one compiled call, the public call's first try (models/runtime/prepared.py): given 1-D float64
      base-class ndarrays (what numba's unboxing trusts, checked by the caller), it checks their layout
      (``dof`` entries, 8 bytes apart, aligned, ``out`` apart from the inputs) and, with ``check``, the
      values as ``check=True`` does, then computes into ``out``: 0 when done; any other answer (a code)
      leaves the call to the checked path, which names the problem. Bound once per model (the kernel's
      compiled entry point with the model's parameters, ``functools.partial``).
    * ``inverse_one(q, qd, qdd, out)``, ``forward_one(q, qd, tau, out)``: one sample, 1-D arrays.
    * ``forward_checked(q, qd, tau) -> qdd``: one validated sample with ``check=True``: the model's
      ``check_regular`` and ``check_finite`` refusals, the common case decided in compiled code
      (models/newton_euler/forward_fused.py).
    * ``inverse_whole(q, qd, qdd, out_or_None)``: any batch, unchunked (O(n) scratch);
      ``forward_whole(q, qd, tau, out_or_None, check)``: the same, with ``check`` the regularity checks'
      common case and the answer's finiteness in the same compiled call, None where it does not take a
      sample (the checked path, ``check_regular`` then ``forward_chunk``, decides and names it).
    * ``inverse_chunk(q, qd, qdd)``, ``forward_chunk``: a batch of at most ``chunk_samples`` samples.
    """

    inverse_fast: Callable[..., Any] | None = None
    forward_fast: Callable[..., Any] | None = None
    inverse_one: Callable[..., Any] | None = None
    forward_one: Callable[..., Any] | None = None
    forward_checked: Callable[..., Any] | None = None
    inverse_whole: Callable[..., Any] | None = None
    forward_whole: Callable[..., Any] | None = None
    inverse_chunk: Callable[..., Any] | None = None
    forward_chunk: Callable[..., Any] | None = None

    def merged(self, other: Entries) -> Entries:
        """Both kernels' entries; each entry is supplied by one kernel only."""
        both = {}
        for f in fields(self):
            a, b = getattr(self, f.name), getattr(other, f.name)
            if a is not None and b is not None:
                raise ValueError(f"two kernels supply the entry {f.name}")
            both[f.name] = a if a is not None else b
        return Entries(**both)


@dataclass(frozen=True)
class Kernel:
    """One kernel of a method: what it computes, for which shapes, its cost and its threading."""

    #: Its name, unique among its method's kernels.
    name: str
    #: The value of the method's option ``kernel`` that runs it.
    option: str
    #: The public calls of :class:`~exo_bench.models.runtime.prepared.PreparedModel` it serves.
    computes: tuple[str, ...]
    #: :data:`ONE_SAMPLE`, :data:`BATCH`, or both.
    shapes: tuple[str, ...]
    #: How it uses threads.
    threading: str
    #: Its cost, in words: which formulas of :mod:`exo_bench.api.cost_formulas` time it, and how.
    cost: str
    #: Its per-sample seconds against the method's cost formulas (measured).
    speed: float = 1.0
    #: Seconds numba takes to compile it on a machine whose cache is empty (None: not compiled).
    compile_seconds: float | None = None
    #: Memory of its runtime, once per process (:data:`NUMBA_BYTES` for numba's).
    runtime_bytes: int = 0
    #: ``load(model) -> Entries``: the kernel bound to one prepared model (imports its code).
    load: Callable[[Any], Entries] | None = field(default=None, compare=False, repr=False)

    @property
    def compiled(self) -> bool:
        """Compiled (by numba) on first use, then loaded from the on-disk cache."""
        return self.compile_seconds is not None


def lean_kernel(cost: str, compile_seconds: float, load: Callable[[Any], Entries], speed: float = 1.0) -> Kernel:
    """The kernel object of a one-sample compiled entry: inverse dynamics of one sample in the calling thread,
    option ``numba``, its entry ``inverse_fast`` bound by ``load``; ``cost`` says against which cost formula."""
    return Kernel(
        "lean",
        "numba",
        ("inverse_dynamics",),
        (ONE_SAMPLE,),
        "one thread: the calling one",
        cost,
        speed=speed,
        compile_seconds=compile_seconds,
        runtime_bytes=NUMBA_BYTES,
        load=load,
    )


def kernel_options(kernels: tuple[Kernel, ...]) -> tuple[str, ...]:
    """The values of the option ``kernel`` of a method with these kernels, the default first."""
    return tuple(dict.fromkeys(k.option for k in kernels))


def select(method: str, kernels: tuple[Kernel, ...], option: object) -> tuple[Kernel, ...]:
    """The kernels that ``option`` runs; a ValueError naming the method and the values otherwise."""
    chosen = tuple(k for k in kernels if isinstance(option, str) and k.option == option)
    if not chosen:
        values = ", ".join(map(repr, kernel_options(kernels)))
        raise ValueError(f"{method}: option 'kernel': expected one of {values}, got {option!r}")
    return chosen


def load(model: Any, kernels: tuple[Kernel, ...]) -> Entries:
    """The entries of ``kernels`` bound to ``model``."""
    entries = Entries()
    for k in kernels:
        if k.load is not None:
            entries = entries.merged(k.load(model))
    return entries


def entry_point(dispatcher: Any, *example: Any) -> Any:
    """The compiled entry point of a numba kernel for the types of ``example`` (loaded from numba's
    on-disk cache, or compiled), or the dispatcher itself where there is none (``NUMBA_DISABLE_JIT``).
    Calling it skips numba's type dispatch (about 0.3 us a call), and trusts the types: a caller
    passes arguments of exactly the example's types (the one-sample entries get C-ordered float64 1-D
    arrays only, checked before)."""
    compile_for = getattr(dispatcher, "compile", None)
    if compile_for is None:
        return dispatcher
    import numba

    return compile_for(tuple(numba.typeof(a) for a in example))


#: Results kept per pool. Two: a loop holds the previous result during the next call.
KEEP = 2
#: Smaller results come from ``np.empty``: glibc's heap recycles those itself (its threshold starts at
#: 128 KiB and rises to the size of any mapped block freed, up to 32 MiB).
MIN_BYTES = 1 << 22


def _refs(pool: list, i: int) -> int:
    """The reference count of ``pool[i]`` as seen from here (the list's, plus this call's own)."""
    return sys.getrefcount(pool[i])


def _own_refs() -> int:
    """:func:`_refs` of an array that only its list refers to: measured, not assumed, since the
    interpreter's own references differ between versions."""
    return _refs([np.empty(1)], 0)


def _own_bound_refs() -> int:
    """The reference count :meth:`ResultPool.empties` reads of an array that only its list refers to,
    bound to a loop variable as there (measured, as :func:`_own_refs`)."""
    for a in [np.empty(1)]:
        return sys.getrefcount(a)
    raise AssertionError


#: False where reference counts are deferred (free-threaded builds): then nothing is recycled.
RECYCLES = bool(getattr(sys, "_is_gil_enabled", lambda: True)())
_OWN = _own_refs()
_OWN_BOUND = _own_bound_refs()


class ResultPool:
    """Float64 results of one prepared model: :meth:`empty` is ``np.empty`` that reuses a dropped
    result of the same shape (module docstring)."""

    def __init__(self, keep: int = KEEP, min_bytes: int = MIN_BYTES):
        self._keep = keep
        self._min_bytes = min_bytes
        self._arrays: list[np.ndarray] = []
        self._lock = threading.Lock()

    def empty(self, shape: tuple[int, ...]) -> np.ndarray:
        """An uninitialised C-ordered float64 array of ``shape`` that no one else refers to."""
        size = 8
        for d in shape:  # not np.prod (3-15 us a call), nor a generator (a frame per step)
            size *= int(d)
        if not RECYCLES or size < self._min_bytes:
            return np.empty(shape)
        shape = tuple(int(d) for d in shape)
        with self._lock:
            arrays = self._arrays
            for i in range(len(arrays)):
                if arrays[i].shape == shape and _refs(arrays, i) == _OWN:
                    return arrays[i]
            new = np.empty(shape)
            self._arrays = [new, *arrays][: self._keep]
            return new

    def empties(self, shape: tuple[int, ...], count: int) -> list[np.ndarray]:
        """``count`` arrays of :meth:`empty` at once, distinct, in one Python call (no generator: the
        derivative calls count the Python functions they run)."""
        out: list[np.ndarray] = []
        size = 8
        for d in shape:  # as empty: not np.prod, nor a generator
            size *= int(d)
        if not RECYCLES or size < self._min_bytes:
            for _ in range(count):
                out.append(np.empty(shape))
            return out
        shape = tuple(map(int, shape))
        with self._lock:
            for a in self._arrays:  # a result handed out in this call is referred to by out: never again
                if len(out) < count and a.shape == shape and sys.getrefcount(a) == _OWN_BOUND:
                    out.append(a)
            new = []
            while len(out) < count:
                new.append(np.empty(shape))
                out.append(new[-1])
            self._arrays = [*new, *self._arrays][: self._keep]
        return out

    def release(self) -> None:
        """Drop the kept results (their memory is freed once their callers drop them too)."""
        with self._lock:
            self._arrays = []

    def __len__(self) -> int:
        return len(self._arrays)


def terms_from_inverse_dynamics(inverse_dynamics, dof: int, q: np.ndarray, qd: np.ndarray):
    """``M (S, dof, dof)`` and ``h (S, dof)`` from any inverse dynamics ``(q, qd, qdd) -> tau`` on
    ``(samples, dof)`` arrays, in ONE batched call.

    Inverse dynamics is linear in ``qdd``: ``ID(q, qd, qdd) = M(q) qdd + h(q, qd)``. Per sample the
    batch holds ``(q, qd, 0)`` (gives ``h``), ``(q, 0, 0)`` (gravity only) and ``(q, 0, e_k)`` for
    every coordinate ``k``; then ``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)``. The subtraction costs at
    most ``eps * |gravity forces| / |M e_k|`` relative, which the tests bound against CRBA.
    """
    return terms_in_chunks(inverse_dynamics, dof, q, qd, (q.shape[0] + 1) * (dof + 2))


def terms_in_chunks(inverse_dynamics, dof: int, q: np.ndarray, qd: np.ndarray, chunk_samples: int):
    """:func:`terms_from_inverse_dynamics` over the rows of ``q, qd`` in chunks of fewer samples, so that
    their ``dof + 2`` inverse-dynamics rows per sample keep the working set of ``chunk_samples`` rows
    (one call where the batch fits)."""
    size, S, k = max(1, chunk_samples // (dof + 2)), q.shape[0], dof + 2
    M, h = np.empty((S, dof, dof)), np.empty((S, dof))
    for s0 in range(0, S, size):  # one batched call per chunk (no helper: one frame, issue 47)
        c = slice(s0, min(S, s0 + size))
        qc, n = q[c], min(S, s0 + size) - s0
        Q = np.repeat(qc, k, axis=0)  # (n*k, d): each sample's q, k times
        QD = np.zeros_like(Q)
        QD[::k] = qd[c]  # first row of each block: the real rates
        QDD = np.zeros_like(Q)
        rows = np.arange(n)[:, None] * k + 2 + np.arange(dof)[None, :]
        QDD[rows.ravel(), np.tile(np.arange(dof), n)] = 1.0
        tau = inverse_dynamics(Q, QD, QDD).reshape(n, k, dof)
        h[c] = tau[:, 0]
        M[c] = np.swapaxes(tau[:, 2:] - tau[:, 1:2], 1, 2)  # column k of M is ID(q, 0, e_k) - ID(q, 0, 0)
    return M, h


def cholesky_solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``M^-1 b`` for symmetric positive definite batches ``(S, d, d)``, ``(S, d)``: Cholesky of
    ``M`` equilibrated by ``D = diag(M)`` (units and coordinate scales drop out), then two
    triangular solves. A matrix that is not positive definite in floating point raises
    :class:`SingularConfigurationError` with its sample (never NaN)."""
    dg = np.diagonal(M, axis1=1, axis2=2)
    bad = ~(dg > 0).all(axis=1)
    if bad.any():
        s = int(np.argmax(bad))
        c = int(np.argmin(dg[s]))
        raise SingularConfigurationError(
            [
                f"sample {s}: M is numerically singular: its diagonal entry {c + 1} is "
                f"{float(dg[s, c])!r} (a rod within rounding of vertical or of length zero)"
            ]
        )
    r = 1.0 / np.sqrt(dg)
    try:
        L = np.linalg.cholesky(M * r[:, :, None] * r[:, None, :])
    except np.linalg.LinAlgError:
        raise SingularConfigurationError(
            [
                "M is not positive definite in floating point (numerically singular: "
                "a rod nearly vertical or nearly of length zero)"
            ]
        ) from None
    y = np.linalg.solve(L, (r * b)[..., None])
    return r * np.linalg.solve(np.swapaxes(L, 1, 2), y)[..., 0]


__all__ = ["PreparedModel", "MissingExtra"]

_ND = np.ndarray
_F8 = np.dtype(np.float64)
_empty = np.empty
#: The names of the state arrays of inverse and of forward dynamics.
_INVERSE_NAMES = ("q", "qd", "qdd")
_FORWARD_NAMES = ("q", "qd", "tau")
_RATES = ("q", "qd")


def _require(method: str, names: Sequence[str], arrays: Sequence[Any]) -> None:
    """The rates a call needs are given: None is not "zero"; a ValueError naming the field."""
    for name, a in zip(names, arrays):
        if a is None:
            raise ValueError(
                f"{method}: field '{name}': expected an array of shape (dof,) or (samples, dof), "
                "got None (pass zeros for a state at rest)"
            )


class MissingExtra(ValueError):
    """A method's optional engine is not installed (e.g. MuJoCo or Drake, extra ``[peers]``): a
    ValueError whose message names the extra; ``skip_reason`` (the same line) makes studies and
    benchmarks skip the method with it instead of failing."""

    def __init__(self, message: str):
        super().__init__(message)
        self.skip_reason = message


def _rebuild(cls, mechanism: Mechanism, options: dict):
    return cls(mechanism, **options)


class PreparedModel:
    """A mechanism prepared for one method. Subclasses set :attr:`method` and either list their
    :attr:`kernels` (and call :meth:`_use_kernels`) or implement :meth:`_inverse_dynamics`; they may
    override ``_mass_matrix``, ``_bias_forces``, ``sample_bytes`` and ``check_regular`` (forward dynamics'
    refusal of singular configurations), never a public call."""

    #: The registry name of the method; the algorithm timed under it.
    method: ClassVar[str] = ""
    #: Every kernel of the method (the tuple its MethodSpec lists; empty: the method's own
    #: :meth:`_inverse_dynamics`). The option ``kernel`` chooses among them (:meth:`_use_kernels`).
    kernels: ClassVar[tuple[Kernel, ...]] = ()
    #: The option ``kernel`` this model runs ("" for a method without the option).
    kernel: str = ""
    #: Its :attr:`derivatives` differentiate the very passes it evaluates (newton-euler), not merely
    #: equations it agrees with to rounding (their ``source`` says which).
    derivatives_are_its_own: ClassVar[bool] = False
    #: Why its results are known to be wrong (None: they are not), in one line; its MethodSpec lists the
    #: same line (exo_bench.api.methods), and its :attr:`derivatives` are then those of the correct equations.
    known_wrong: ClassVar[str | None] = None
    #: The entries of the chosen kernels (:class:`~exo_bench.models.runtime.prepared.Entries`, bound by
    #: :meth:`_use_kernels`; each None where none supplies it): what the calls below run. Set on the
    #: instance only: a class-level default (an instance of a mutable class) kept Python 3.11 from
    #: specialising ``self._entries`` in the calls, about 65 ns of a 0.45 us one-sample call.
    _entries: Entries
    __slots__ = ("_entries", "__dict__")
    _chunk: int
    _results: ResultPool
    _mechanism: Mechanism
    #: forward dynamics' compiled checks ``(clear, finite)`` (models/runtime/forward_check.py), resolved on first use
    _forward_checks: tuple[Callable[..., bool], Callable[..., bool]] | None = None
    #: their plan (:func:`exo_bench.models.runtime.forward_check.plan_of`), with them
    forward_plan: Any = None

    def __init__(self, mechanism: Mechanism, **options: Any):
        if not isinstance(mechanism, Mechanism):
            raise ValueError(
                f"{self.method}: expected a Mechanism (exo_bench.Mechanism or exo_bench.load_mechanism), "
                f"got {type(mechanism).__name__}"
            )
        self._mechanism = mechanism
        self._options = dict(options)
        self._dof = mechanism.dof
        self._chunk = default_chunk_samples(mechanism.dof, self.sample_bytes(mechanism.nlinks, mechanism.dim))
        self._results = ResultPool()  # new batched results, recycled once dropped (models/runtime/prepared.py)
        self._entries = Entries()  # no kernel's entries until _use_kernels

    # ------------------------------------------------------------------ what it is
    @property
    def mechanism(self) -> Mechanism:
        return self._mechanism

    @property
    def options(self) -> dict:
        """The constructor options this model was prepared with (a copy)."""
        return dict(self._options)

    @property
    def dof(self) -> int:
        return self._dof

    @property
    def native_terms(self) -> bool:
        """True when :meth:`mass_matrix` and :meth:`bias_forces` are the method's own, False when
        they are derived from its inverse dynamics."""
        return type(self)._mass_matrix is not PreparedModel._mass_matrix

    def __repr__(self) -> str:
        opts = "".join(f", {k}={v!r}" for k, v in self._options.items())
        return f"<{type(self).__name__} {self.method!r} of {self._mechanism.name!r} ({self._dof} dof){opts}>"

    def __reduce__(self):
        return (_rebuild, (type(self), self._mechanism, self._options))

    @property
    def derivatives(self):
        """The derivatives of this model's equations of motion, built on first use:
        ``.inverse_dynamics(q, qd, qdd) -> (dtau_dq, dtau_dqd, M)``, ``.forward_dynamics(q, qd, tau)
        -> (qdd, dqdd_dq, dqdd_dqd, Minv)``, batch-first, their directional derivatives (``*_jvp``,
        ``*_vjp``) and ``.source`` (which physics computes them): the analytic derivatives of the
        Newton-Euler passes for every method, :mod:`exo_bench.models.derivatives` (CasADi's stay in
        :mod:`exo_bench.matrix_method.derivatives`), their ``source`` from this class's facts
        (:attr:`derivatives_are_its_own`, :attr:`known_wrong`)."""
        if getattr(self, "_derivatives", None) is None:
            from exo_bench.models.derivatives import Derivatives, source_text

            cls = type(self)
            source = source_text(self.method, cls.derivatives_are_its_own, cls.known_wrong is not None)
            self._derivatives = Derivatives(self._mechanism, self.method, source)
        return self._derivatives

    # ------------------------------------------------------------------ kernels
    def _use_kernels(self, option: object) -> str:
        """Run the kernels of the option ``kernel`` (``option``; a ValueError naming the values
        otherwise): their entries (:class:`~exo_bench.models.runtime.prepared.Entries`), bound to this model, are
        what the calls below run. Called by a method with kernels once its arguments are prepared."""
        chosen = select(self.method, self.kernels, option)
        self._entries = load(self, chosen)
        self.kernel = self._options["kernel"] = chosen[0].option
        return self.kernel

    # ------------------------------------------------------------------ chunks
    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float | None:
        """Bytes of one sample's temporaries in a batch, measured (the cost model's figure, which
        sizes the chunks); None: the bound of :func:`~exo_bench.models.machine.memory.default_chunk_samples`."""
        return None

    @property
    def chunk_samples(self) -> int:
        """Samples evaluated at a time: batches longer than this are split into chunks written
        into one preallocated result (the working set stays that of one chunk)."""
        return self._chunk

    @chunk_samples.setter
    def chunk_samples(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{self.method}: chunk_samples: expected an integer >= 1, got {value!r}")
        self._chunk = int(value)

    def _chunked(
        self, fn: Callable[..., np.ndarray], arrays: Sequence[np.ndarray], out_shape: tuple[int, ...]
    ) -> np.ndarray:
        """``fn(*chunks)`` over the rows of ``arrays`` in chunks of :attr:`chunk_samples`, into one
        result of shape ``(S, *out_shape)``; one call when the batch fits in a chunk."""
        S = arrays[0].shape[0]
        if S <= self._chunk:
            return fn(*arrays)
        out = self._results.empty((S, *out_shape))
        for c in chunks(S, self._chunk):
            out[c] = fn(*(a[c] for a in arrays))
        return out

    # ------------------------------------------------------------------ regularity
    def check_regular(self, q: np.ndarray) -> None:
        """Raise :class:`~exo_bench.models.mechanism.singularity.SingularConfigurationError` where ``M(q)`` is exactly
        singular (a rod of length zero or, 3D, vertical, or the mechanism's mass coupling:
        :func:`exo_bench.models.mechanism.singularity.singular_reasons`), then where it is singular to working
        precision: the conditioning test that every method shares, O(n) per sample
        (:func:`exo_bench.models.runtime.conditioning.check_conditioning`). The common case, a state clear of every
        bound, is decided by one compiled pass (:mod:`exo_bench.models.runtime.forward_check`); near a bound the
        exact checks decide and name the sample, the link and the reason. A method may override it with
        its own O(n) test (newton-euler does)."""
        if (self._forward_checks or self._resolve_forward_checks())[0](q):  # compiled: the common case
            return
        q = q if q.ndim == 2 else q.reshape(1, -1)
        reasons = [f"sample {s}: {r}" for s, rs in enumerate(singular_reasons(self._mechanism, q)) for r in rs]
        if reasons:
            raise SingularConfigurationError(reasons)
        check_conditioning(self._mechanism, q, self.coupling_condition)

    def _resolve_forward_checks(self) -> tuple[Callable[..., bool], Callable[..., bool]]:
        """``(clear, finite)`` (models/runtime/forward_check.py :func:`checks`) and their plan, kept."""
        from exo_bench.models.runtime.forward_check import checks, plan_of

        self.forward_plan = plan_of(self._mechanism, self.coupling_condition)
        self._forward_checks = checks(self._mechanism.nlinks, self.forward_plan)
        return self._forward_checks

    @property
    def coupling_condition(self) -> CouplingCondition:
        """The mechanism's part of the condition of ``M`` (:func:`exo_bench.models.runtime.conditioning.coupling_condition`),
        O(n), estimated on first use."""
        c = getattr(self, "_coupling_condition", None)
        if c is None:
            c = self._coupling_condition = coupling_condition(self._mechanism)
        return c

    # ------------------------------------------------------------------ calls
    def inverse_dynamics(self, q, qd, qdd, check: bool = True, out=None, f_ext=None) -> np.ndarray:
        """Generalised forces ``tau = [M_phi..., M_psi..., F...]`` of the paper's absolute
        coordinates for states in block order ``[phi..., psi..., l...]``: ``(dof,)`` in gives
        ``(dof,)`` out, ``(samples, dof)`` gives ``(samples, dof)``. ``out``: a preallocated
        C-ordered float64 ndarray of the result's shape, written and returned (a loop of calls then
        allocates nothing: the compiled kernels write into it directly). Without ``out``, a result of
        4 MiB or more reuses the memory of one this model returned before, once nothing refers to that
        one any more (:mod:`exo_bench.models.runtime.prepared`: at most two stay allocated after the caller
        dropped them). ``f_ext``: forces at the point masses, ``(samples, links, 3, dim)`` or ``(links, 3,
        dim)`` (:mod:`exo_bench.models.runtime.external_forces`): ``tau = ID - Q(q, f_ext)``."""
        # one sample: the kernel's compiled entry checks the rest (layout, values) and answers 0 when done
        if (
            (fast := self._entries.inverse_fast) is not None
            and type(q) is _ND
            and type(qd) is _ND
            and type(qdd) is _ND
            and q.ndim == 1
            and qd.ndim == 1
            and qdd.ndim == 1
            and q.dtype is _F8
            and qd.dtype is _F8
            and qdd.dtype is _F8
            and f_ext is None
        ):
            if out is None:
                if not fast(q, qd, qdd, o := _empty(self._dof), check):
                    return o
            elif type(out) is _ND and out.ndim == 1 and out.dtype is _F8 and out.flags.writeable:
                if not fast(q, qd, qdd, out, check):
                    return out
        return self._dynamics(False, q, qd, qdd, check, out, f_ext)

    def forward_dynamics(self, q, qd, tau, check: bool = True, out=None, f_ext=None) -> np.ndarray:
        """Forward dynamics: the accelerations ``qdd`` with ``M(q) qdd + h(q, qd) = tau``, same shapes
        and ``out`` as :meth:`inverse_dynamics`. With ``check`` (the default) the states are
        validated and a singular configuration raises
        :class:`~exo_bench.models.mechanism.singularity.SingularConfigurationError` (a ValueError) naming the sample, the
        link and the reason (zero length, vertical rod, zero mass), never NaN. A method solves
        ``M qdd = tau - h`` by Cholesky on its own ``M`` and ``h`` unless a kernel supplies forward
        dynamics (newton-euler's O(n) passes; its checked one sample: ``tree-forward``, checks and passes
        in one compiled call, models/runtime/forward_check.py). ``f_ext``: forces at the point masses, as in
        :meth:`inverse_dynamics`: ``qdd = FD(q, qd, tau + Q(q, f_ext))``."""
        if (
            (fast := self._entries.forward_fast) is not None
            and type(q) is _ND
            and type(qd) is _ND
            and type(tau) is _ND
            and q.ndim == 1
            and qd.ndim == 1
            and tau.ndim == 1
            and q.dtype is _F8
            and qd.dtype is _F8
            and tau.dtype is _F8
            and f_ext is None
        ):
            if out is None:
                if not fast(q, qd, tau, o := _empty(self._dof), check):
                    return o
            elif type(out) is _ND and out.ndim == 1 and out.dtype is _F8 and out.flags.writeable:
                if not fast(q, qd, tau, out, check):  # out written only when done
                    return out
        return self._dynamics(True, q, qd, tau, check, out, f_ext)

    def _dynamics(self, forward: bool, q, qd, y, check: bool, out, f_ext) -> np.ndarray:
        """The path of :meth:`inverse_dynamics` (``y = qdd``) and :meth:`forward_dynamics` (``forward``,
        ``y = tau``) for every call the one-sample entry does not take: the gate, the checks, the kernel."""
        method, dof, e = self.method, self._dof, self._entries
        if f_ext is not None:
            run = external_forces.forward_dynamics if forward else external_forces.inverse_dynamics
            return run(self, q, qd, y, f_ext, check, out)
        names = _FORWARD_NAMES if forward else _INVERSE_NAMES
        if (s := getattr(q, "shape", None)) is not None and len(s) == 2 and 32.0 * dof * s[0] > CHUNK_BYTES:
            check_batch("forward dynamics" if forward else "inverse dynamics", q, dof, 4 * dof)  # before any copy
        if qd is None or y is None:
            _require(method, names[1:], (qd, y))
        single = q.ndim == 1 if type(q) is _ND else is_one_sample(q)
        if not check:
            q, qd, y = gate_states((q, qd, y), names, dof, method, False)
        elif not forward:
            q, qd, y = checked_states(self._mechanism, q, qd, y)  # plain; one plain sample stays 1-D
        else:
            try:
                q, qd, y = checked_states(self._mechanism, q, qd, y, source="forward dynamics")
            except ValueError as err:  # the third array of the states' check is called qdd: here it is tau
                raise ValueError(
                    str(err).replace("field 'qdd'", "field 'tau'").replace("qdd must", "tau must")
                ) from None
        if out is not None:  # check=True: an out that overlaps an input is written through a copy
            out = as_out(out, (dof,) if single else q.shape, method, () if check else (q, qd, y), names)
        into = out if out is None or not check or apart(out, (q, qd, y)) else None
        if single:
            if q.ndim == 2:
                q, qd, y = q[0], qd[0], y[0]
            r = self._one(forward, q, qd, y, check, into)
        elif not forward:
            r = (
                self._chunked(self._inverse_dynamics, (q, qd, y), (dof,))
                if e.inverse_whole is None
                else (e.inverse_whole(q, qd, y, into))
            )
        elif e.forward_whole is None or (r := e.forward_whole(q, qd, y, None if check else into, check)) is None:
            if check:
                self.check_regular(q)
            r = self._chunked(self._forward_dynamics, (q, qd, y), (dof,))
            if check and not (self._forward_checks or self._resolve_forward_checks())[1](r):
                check_finite(self._mechanism, r)  # never NaN or inf (forces too large for float64): named
        if out is None or r is out:
            return r
        out[...] = r
        return out

    def _one(self, forward: bool, q, qd, y, check: bool, out) -> np.ndarray:
        """One gated (and, with ``check``, validated) sample, 1-D: the kernel's one-sample entries, else the
        batch path on a batch of one."""
        e, dof = self._entries, self._dof
        if forward:
            if check and (checked := e.forward_checked) is not None:  # checks and passes compiled
                return checked(q, qd, y)
            if not check and e.forward_one is not None:
                return e.forward_one(q, qd, y, _empty(dof) if out is None else out)
            q2 = q[None]
            if check:
                self.check_regular(q2)
            r = self._forward_dynamics(q2, qd[None], y[None])
            if check and not (self._forward_checks or self._resolve_forward_checks())[1](r):
                check_finite(self._mechanism, r)
            return r[0]
        if e.inverse_one is not None:
            return e.inverse_one(q, qd, y, _empty(dof) if out is None else out)
        return self._inverse_dynamics(q[None], qd[None], y[None])[0]

    def mass_matrix(self, q, check: bool = True) -> np.ndarray:
        """The mass matrix ``M(q) = d tau / d qdd``, ``(dof, dof)`` or ``(samples, dof, dof)``."""
        d = self._dof
        single = q.ndim == 1 if type(q) is _ND else is_one_sample(q)
        if (s := getattr(q, "shape", None)) is not None and len(s) == 2 and 8.0 * d * (d + 1) * s[0] > CHUNK_BYTES:
            check_batch("mass matrix", q, d, d * (d + 1))
        (q,) = checked_states(self._mechanism, q)[:1] if check else gate_states((q,), ("q",), d, self.method, False)
        if q.ndim == 1:
            q = q[None]
        if type(self)._mass_matrix is PreparedModel._mass_matrix:  # derived from inverse dynamics
            inverse = self._entries.inverse_chunk or self._inverse_dynamics
            M = terms_in_chunks(inverse, d, q, np.zeros_like(q), self._chunk)[0]
        else:
            M = self._chunked(self._mass_matrix, (q,), (d, d))
        return M[0] if single else M

    def bias_forces(self, q, qd, check: bool = True) -> np.ndarray:
        """``h(q, qd) = tau(q, qd, 0)``: Coriolis, centrifugal and gravity forces."""
        d = self._dof
        single = q.ndim == 1 if type(q) is _ND else is_one_sample(q)
        if (s := getattr(q, "shape", None)) is not None and len(s) == 2 and 24.0 * d * s[0] > CHUNK_BYTES:
            check_batch("bias forces", q, d, 3 * d)
        if qd is None:
            _require(self.method, ("qd",), (qd,))
        q, qd = (
            checked_states(self._mechanism, q, qd)[:2] if check else gate_states((q, qd), _RATES, d, self.method, False)
        )
        if q.ndim == 1:
            q, qd = q[None], qd[None]
        if type(self)._bias_forces is PreparedModel._bias_forces and (whole := self._entries.inverse_whole):
            h = whole(q, qd, np.zeros_like(q), None)  # the kernel of any batch, with qdd = 0
        else:
            h = self._chunked(self._bias_forces, (q, qd), (d,))
        return h[0] if single else h

    def mass_matrix_and_bias(self, q, qd, check: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Both terms of ``M qdd + h = tau`` at once, ``(S, dof, dof)`` and ``(S, dof)`` (batch only):
        one batched inverse-dynamics call where the terms are derived."""
        d = self._dof
        check_batch("mass_matrix_and_bias", q, d, d * (d + 4))
        if qd is None:
            _require(self.method, ("qd",), (qd,))
        if (q.ndim if type(q) is _ND else np.ndim(q)) != 2:
            raise ValueError(
                f"{self.method}: mass_matrix_and_bias takes a batch: expected q of shape (samples, "
                f"{d}), got {np.shape(q)}"
            )
        q, qd = (
            checked_states(self._mechanism, q, qd)[:2] if check else gate_states((q, qd), _RATES, d, self.method, False)
        )
        return self._terms(q, qd)

    def _terms(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``M`` and ``h`` of a validated batch: the method's own, or derived from its inverse dynamics."""
        d = self._dof
        if self.native_terms:
            return (self._chunked(self._mass_matrix, (q,), (d, d)), self._chunked(self._bias_forces, (q, qd), (d,)))
        return terms_in_chunks(self._entries.inverse_chunk or self._inverse_dynamics, d, q, qd, self._chunk)

    # ------------------------------------------------------------------ per method
    def _inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Inverse dynamics of a validated batch of at most :attr:`chunk_samples` samples: the
        kernels' entry, or the method's own code (a method without kernels overrides this)."""
        if (chunk := self._entries.inverse_chunk) is None:
            raise NotImplementedError(f"{self.method}: no inverse dynamics")
        return chunk(q, qd, qdd)

    def _mass_matrix(self, q: np.ndarray) -> np.ndarray:
        return terms_in_chunks(self._inverse_dynamics, self._dof, q, np.zeros_like(q), self._chunk)[0]

    def _bias_forces(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self._inverse_dynamics(q, qd, np.zeros_like(q))

    def _external_forces(self, q: np.ndarray, f: np.ndarray) -> np.ndarray:
        """``Q = sum_k J_k^T f_k``, ``(S, dof)``, of forces ``f`` ``(S, links, 3, dim)`` at the point masses
        (:mod:`exo_bench.models.runtime.external_forces`); an engine overrides it with its own."""
        from exo_bench.models.runtime.external_forces import (  # the parameters, bound once on the model
            bound,
            generalized_forces_compiled,
        )

        return generalized_forces_compiled(self._mechanism, q, f, bound(self).params)

    def _forward_dynamics(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
        if (chunk := self._entries.forward_chunk) is not None:
            return chunk(q, qd, tau)
        M, h = self._terms(q, qd)
        return cholesky_solve(M, tau - h)
