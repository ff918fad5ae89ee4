"""Kernels: the code a method runs, each an object listed in the method's
:class:`~exo_bench.api.methods.MethodSpec` (and its prepared-model class's ``kernels``).

A :class:`Kernel` states what it computes (the public calls it serves), for which shapes (one sample,
a batch), its cost (against the method's cost formulas, :mod:`exo_bench.api.cost_formulas`) and its
threading; :attr:`Kernel.load` binds it to one prepared model (its coefficients, its compiled
entry points), giving :class:`Entries`. The option ``kernel`` of a method names a group of its
kernels (``kernel="numba"`` runs matrix-factored's per-sample, SIMD and lean kernels); the public
calls are :class:`~exo_bench.models.prepared.PreparedModel`'s, which run the entries: a method never
overrides them. Adding a kernel is one module (its code and a ``load``) and one entry in the tuple of
its method's kernels (docs/add-a-kernel.md).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any

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
      sample in one compiled call, the public call's first try (models/prepared.py): given 1-D float64
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
    #: The public calls of :class:`~exo_bench.models.prepared.PreparedModel` it serves.
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
