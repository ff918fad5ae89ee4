"""Memory and time of a method, estimated before it runs, and the limits that refuse it.

:func:`estimate` gives, for a mechanism, a method and a batch size, the peak memory and the
seconds of a run through a prepared model: the one-time setup (Pinocchio's ``Data``, Lagrange's
derivation, the matrix family's coefficients), the batch's arrays (``q, qd, qdd`` and ``tau``)
and one chunk's temporaries (batches are evaluated in chunks of :func:`chunk_samples`, so the
temporaries do not grow with the batch). :func:`check` refuses, with one line that names the
method, the estimate, the limit, how to raise it and a method that fits, when the estimate
exceeds the memory limit (default: :data:`USABLE_SHARE` of the machine's available memory,
``--max-memory``) or a time
limit (``--max-time``, and for ``lagrange`` its derivation budget, ``--budget``).

**The cost model.** Per method, memory is ``setup + arrays + chunk x per-sample bytes`` and time is
``setup + calls x per-call + samples x per-sample seconds``, each a small formula in ``n`` (links)
and ``dim``, in :mod:`exo_bench.api.cost_formulas` (one per method, named by its MethodSpec). The constants were fitted to measurements taken by
:func:`exo_bench.bench.perf.calibration.measure` (``python -m exo_bench.bench.perf.calibration``: each point in a fresh process; memory is
the growth of the peak resident set size, ``VmHWM`` after a reset through /proc/self/clear_refs,
because Pinocchio allocates in C++ where tracemalloc does not see; time is ``perf_counter``), on
chains of n = 5, 25 and 100 links (lagrange: 1 to 30) in 2D and 3D with batches of 1 and 2000
samples, on a 2-core x86-64 machine shared with other jobs (pin 4.1.0, numpy 2.4, sympy 1.14).
Memory is rounded up (an estimate that is too high refuses a run that would fit; one too low lets
a run be killed). Times are indicative, the same machine's; Lagrange's derivation time is not
rounded up, so that a refusal for its budget is a real one.

Measured against estimated by :func:`exo_bench.bench.perf.calibration.calibration_table`: the table in
docs/cost-model.md (the estimate without :data:`BASE_BYTES`; afterwards ``matrix`` in 3D went from 40 to
44 n^2 floats per sample).

Since 2026-11-24: the times of ``recurrence``, ``pinocchio`` and ``matrix-factored`` are recalibrated
(:mod:`exo_bench.api.cost_formulas`: the quiet machine's times :data:`~exo_bench.api.cost_formulas.LOADED`,
and a large batch no faster than :data:`~exo_bench.api.cost_formulas.ARRAY_BANDWIDTH`); that table had
them 3-17x too slow per sample (the compiled and SIMD kernels came after it), so that the timing goal (bench/test_estimate_timing.py)
found the quiet machine 0.17x the estimates. The other methods keep its figures.

Since issue 26: ``recurrence``'s setup counts its increment tables (:func:`~exo_bench.api.cost_formulas.recurrence_table_floats`:
sum over links of m^2, m = the link and its ancestors; n^3 / 3 for a chain, written once into one array:
3.5 GB and 20 s estimated at 2D n = 1000, measured 3.0 GB and 12.7 s, where the former four copies
measured 10.6 GB and 32 s), ``pinocchio``'s setup time the first
touch of its Data and the model build, and ``io`` (bench/cli/states_input.py) the reading of the states
and the writing of tau; bench/test_estimate_timing.py holds recurrence and Pinocchio within 2x
of measurement across n (a benchmark: --benchmark-enable), and tests/test_estimate_vs_measured.py the memory
estimate above the allocations tracemalloc counts.

Setup: ``pinocchio`` is one ``pin.Data`` (``models.pinocchio_backend.data_bytes``: 32 nv^3 bytes
and more, 0.90 GB at 3D n = 100, zero-filled at about 2.7 GB/s by ``pin.Data(model)``; ``createData()``
would copy it, twice the peak) plus its model (9 MB at 3D n = 100);
the matrix family keeps ``n x n`` coefficient matrices, and its compiled kernels (option
``kernel="numba"``, the default of ``matrix``, ``matrix-factored``, ``recurrence``) add numba's
runtime on first use and, when numba's on-disk cache lacks them, a one-time compile
(the kernel objects' ``runtime_bytes``, :data:`~exo_bench.models.runtime.prepared.NUMBA_BYTES`, and ``compile_seconds``, named in the note); per sample the compiled kernels need less
time and memory (``threads x`` one sample's scratch) than the numpy kernels whose figures the
model keeps, so those estimates are conservative for them; ``lagrange`` derives with sympy:
2D n = 5: 0.9 s, 18 MB; n = 10: 4.2 s, 70 MB; n = 20: 43 s, 674 MB; n = 30: 175 s, 3.1 GB; 3D n = 5: 2.8 s, 37 MB; n = 10:
17 s, 242 MB (all points in :data:`~exo_bench.api.cost_formulas.LAGRANGE_POINTS`, interpolated in log-log and extended beyond the
largest n by the power law through the last two points: about n^3.5 in time and n^3.7 in memory).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from exo_bench.api.cost_formulas import ARRAY_BANDWIDTH, BASE_BYTES, F8, LOADED, _loglog, _seconds, _size, kernel_note
from exo_bench.api.methods import METHODS, method_class, preference
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.machine.memory import USABLE_SHARE, default_chunk_samples, usable_memory


def sample_bytes(mech: Mechanism, method: str) -> float:
    """Bytes of one sample's temporaries of ``method`` on ``mech`` (the prepared-model class's figure)."""
    per = method_class(method).sample_bytes(mech.nlinks, mech.dim)
    return 8.0 * (mech.dof * mech.dof + 64 * mech.dof) if per is None else float(per)


def chunk_samples(mech: Mechanism, method: str) -> int:
    """Samples per chunk of ``method`` on ``mech``: the chunk its prepared model uses (one chunk's
    temporaries near :data:`~exo_bench.models.machine.memory.CHUNK_BYTES`)."""
    return default_chunk_samples(mech.dof, sample_bytes(mech, method))


@dataclass(frozen=True)
class Estimate:
    method: str
    samples: int
    setup_bytes: float
    array_bytes: float  # q, qd, qdd and tau of the whole batch
    chunk_bytes: float  # one chunk's temporaries
    seconds: float
    setup_seconds: float
    note: str = ""
    io_bytes: float = 0.0  # the peak of reading the states (before the method's work starts)

    @property
    def memory(self) -> float:
        return BASE_BYTES + max(self.io_bytes, self.setup_bytes + self.array_bytes + self.chunk_bytes)

    def describe(self) -> str:
        return f"about {_size(self.memory)} and {_seconds(self.seconds)}"


def estimate(
    mech: Mechanism, method: str, samples: int = 1, options: dict | None = None, io: tuple[float, float] = (0.0, 0.0)
) -> Estimate:
    """The estimated peak memory and seconds of ``samples`` samples of ``method`` on ``mech``
    through a prepared model, including the setup (see the module docstring); ``io``: the peak
    bytes of reading the states and the seconds of reading them and writing tau
    (bench/cli/states_input.py), counted in."""
    options = dict(options or {})
    model = METHODS[method].cost if method in METHODS else None
    kernels = METHODS[method].kernels_for(options.get("kernel")) if method in METHODS else ()
    io_bytes, io_seconds = (float(x) for x in io)
    array_bytes = 4.0 * F8 * mech.dof * samples  # q, qd, qdd and tau
    if model is None:  # a method registered without a cost model: its arrays only
        return Estimate(method, samples, 0.0, array_bytes, 0.0, io_seconds, 0.0, "no cost model", io_bytes)
    n, d = mech.nlinks, mech.dim
    chunk = min(max(samples, 1), chunk_samples(mech, method))
    calls = math.ceil(max(samples, 1) / chunk)
    setup_s = model.setup_seconds(mech, options)
    per_sample = samples * model.sample_seconds(n, d)
    chunk_bytes = chunk * sample_bytes(mech, method)
    # the kernels' speed against the method's figures (matrix's compiled kernel: about half, issue 26); the
    # chunk's temporaries stay the numpy kernel's, an upper bound of the compiled one's (bench/test_memory.py)
    per_sample *= min((k.speed for k in kernels), default=1.0)
    # a large batch streams its arrays: no faster than ARRAY_BANDWIDTH (on the loaded reference machine)
    per_sample = max(per_sample, array_bytes * LOADED / ARRAY_BANDWIDTH)
    seconds = setup_s + calls * model.call_seconds + per_sample + io_seconds
    return Estimate(
        method,
        samples,
        float(model.setup_bytes(mech, options) + max((k.runtime_bytes for k in kernels), default=0)),
        array_bytes,
        float(chunk_bytes),
        float(seconds),
        float(setup_s),
        model.note(mech, options) + kernel_note(kernels),
        io_bytes,
    )


class ResourceLimit(ValueError):
    """A method's estimated memory or time exceeds a limit. ``skip_reason`` is the one-line
    message (a study records the method as skipped with it); ``budget`` names the limit."""

    def __init__(self, message: str, budget: str):
        super().__init__(message)
        self.skip_reason = message
        self.budget = budget


@dataclass
class Limits:
    """The limits a run is held to: ``memory`` in bytes (None: the available memory),
    ``seconds`` (None: no limit) and ``budget``, Lagrange's derivation budget in seconds."""

    memory: float | None = None
    seconds: float | None = None
    budget: float | None = None
    memory_source: str = field(default="")

    def memory_limit(self) -> tuple[float | None, str]:
        if self.memory is not None:
            return float(self.memory), self.memory_source or "--max-memory"
        usable = usable_memory()
        return (
            (None if usable is None else float(usable)),
            f"{USABLE_SHARE:.0%} of the available memory; set the limit with --max-memory",
        )


def _over(est: Estimate, limits: Limits, options: dict | None = None) -> str | None:
    """Which limit the estimate exceeds, as a phrase, or None (``options``: the method's; a
    ``budget`` there is Lagrange's derivation budget when ``limits`` names none)."""
    # lagrange's derivation budget first: the most specific reason (prepare() names it)
    if est.method in METHODS and METHODS[est.method].derivation_budget:
        from exo_bench.lagrange.numeric import DEFAULT_BUDGET  # noqa: PLC0415 - only for lagrange

        budget = limits.budget if limits.budget is not None else (options or {}).get("budget", DEFAULT_BUDGET)
        valid = not isinstance(budget, bool) and isinstance(budget, (int, float)) and budget > 0
        if valid and est.setup_seconds > budget:  # (not a budget: the method's constructor says so)
            return (
                f"its derivation alone over the budget of {_seconds(budget)} (raise it with --budget SECONDS, "
                "or prepare()'s option budget)"
            )
    mem, mem_src = limits.memory_limit()
    if mem is not None and est.memory > mem:
        return f"over the memory limit of {_size(mem)} ({mem_src})"
    if limits.seconds is not None and est.seconds > limits.seconds:
        return f"over the time limit of {_seconds(limits.seconds)} (--max-time)"
    return None


def fitting_method(
    mech: Mechanism,
    samples: int,
    limits: Limits,
    exclude: str = "",
    options: dict[str, dict] | None = None,
    io: tuple[float, float] = (0.0, 0.0),
) -> Estimate | None:
    """The first method of :func:`~exo_bench.api.methods.preference` whose estimate is within the limits."""
    for m in preference():
        if m == exclude:
            continue
        est = estimate(mech, m, samples, (options or {}).get(m), io)
        if _over(est, limits) is None:
            return est
    return None


def check(
    mech: Mechanism,
    method: str,
    samples: int = 1,
    options: dict | None = None,
    limits: Limits | None = None,
    io: tuple[float, float] = (0.0, 0.0),
) -> Estimate:
    """The estimate of ``method``, or :class:`ResourceLimit` when it exceeds ``limits``: one line
    naming the method, the estimate and what dominates it, the limit and how to raise it, and a
    method that fits (or that none does, and why). ``io``: see :func:`estimate`."""
    limits = limits or Limits()
    est = estimate(mech, method, samples, options, io)
    over = _over(est, limits, options)
    if over is None:
        return est
    size = f"n={mech.nlinks} links, dim={mech.dim}, {samples} sample(s)"
    note = f" ({est.note})" if est.note else ""
    if io[1] > 0.05 * est.seconds:  # named where it matters
        note += f" (reading the states and writing tau: {_seconds(io[1])} of it)"
    msg = f"method {method!r} on {mech.name!r} ({size}) needs {est.describe()}{note}, {over}"
    alt = fitting_method(mech, samples, limits, exclude=method, io=io)
    if alt is not None:
        msg += f"; {alt.method} fits: {alt.describe()}"
    else:
        arrays = BASE_BYTES + max(est.array_bytes, est.io_bytes)
        mem, _ = limits.memory_limit()
        if mem is not None and arrays > mem:
            msg += f"; no method fits: the batch's arrays alone take {_size(arrays)}: split the batch"
        else:
            msg += "; no method fits these limits"
    budget = "memory" if "memory limit" in over else ("time" if "time limit" in over else "budget")
    raise ResourceLimit(msg, budget)


def check_reading(path: str, read_bytes: float, read_seconds: float, limits: Limits | None = None) -> None:
    """Refuse (:class:`ResourceLimit`) reading a states file whose reading alone exceeds the limits
    (a JSON file, whose samples are known only once it is parsed: bench/cli/states_input.py)."""
    limits = limits or Limits()
    mem, src = limits.memory_limit()
    need = BASE_BYTES + read_bytes
    over = (
        f"over the memory limit of {_size(mem)} ({src})"
        if mem is not None and need > mem
        else f"over the time limit of {_seconds(limits.seconds)} (--max-time)"
        if limits.seconds is not None and read_seconds > limits.seconds
        else None
    )
    if over:
        raise ResourceLimit(
            f"states {path!r}: reading it needs about {_size(need)} and {_seconds(read_seconds)} "
            f"(JSON), {over}; give the states as a .npz archive (read about 20 times faster) or "
            "split the batch",
            "memory" if "memory" in over else "time",
        )


#: Arrays a scene's motion and study hold per sample and coordinate: t, q, qd, qdd, and per
#: method its tau and a difference (the scene's methods, up to six).
SCENE_ARRAYS = 16


def check_samples(mech: Mechanism, samples: int, limits: Limits | None = None, what: str = "motion") -> float:
    """Refuse (:class:`ResourceLimit`) a motion whose arrays alone would exceed the memory limit,
    before it is built; return their estimated bytes."""
    limits = limits or Limits()
    need = BASE_BYTES + SCENE_ARRAYS * F8 * (mech.dof + 1) * max(samples, 0)
    mem, src = limits.memory_limit()
    if mem is not None and need > mem:
        raise ResourceLimit(
            f"{what}: {samples} samples of {mech.dof} coordinates need about {_size(need)} of arrays, "
            f"over the memory limit of {_size(mem)} ({src}); use fewer samples",
            "memory",
        )
    return need


def parse_size(text: str) -> int:
    """``"2G"``, ``"512M"``, ``"1.5GB"``, ``"2GiB"``, ``"1e9"`` -> bytes (K, M, G, T are powers of 1024)."""
    import re

    t = str(text).strip()
    m = re.fullmatch(r"(?i)([0-9]*\.?[0-9]+(?:e[+-]?[0-9]+)?)\s*([kmgt]?)(i?b)?", t)
    if not m:
        raise ValueError(f"--max-memory: expected a size such as 2G, 512M or 1.5e9 (bytes), got {text!r}")
    value = float(m.group(1)) * 1024 ** " kmgt".index((m.group(2) or " ").lower())
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"--max-memory: expected a positive size, got {text!r}")
    return int(value)


def parse_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--max-time: expected a number of seconds, got {text!r}") from None
    if not math.isfinite(value) or value <= 0:
        raise ValueError(f"--max-time: expected a positive number of seconds, got {text!r}")
    return value


#: ``exo-bench equations``: seconds to compose and generate, measured on chains (one run each on
#: the shared 2-core machine; python and c: three CSEs and the printing, latex: the Markdown page
#: and the .tex): format -> dim -> ((n, seconds), ...). Interpolated in log-log and extended by the
#: power law through the last two points (about n^2 for code, n^4 for latex), not rounded up, so
#: that a refusal for the budget is a real one.
EQUATIONS_POINTS: dict[str, dict[int, tuple[tuple[int, float], ...]]] = {
    "python": {2: ((2, 0.05), (5, 0.14), (10, 0.57), (20, 2.4)), 3: ((2, 0.13), (5, 0.95), (10, 3.5), (20, 13.7))},
    "c": {2: ((2, 0.04), (5, 0.08), (10, 0.53), (20, 3.5)), 3: ((2, 0.05), (5, 1.07), (10, 2.5), (20, 15.7))},
    "latex": {2: ((2, 0.02), (5, 0.05), (10, 0.3), (20, 4.0)), 3: ((2, 0.07), (5, 0.45), (10, 1.5), (20, 26.0))},
    # building and serialising the six CasADi functions of chains (matrix_method/export/casadi_functions.py), 2026-11-23
    "casadi": {2: ((2, 0.07), (5, 0.04), (10, 0.11), (20, 0.28)), 3: ((2, 0.02), (5, 0.06), (10, 0.17), (20, 0.84))},
}


def equations_estimate(mech: Mechanism, fmt: str) -> float:
    """Estimated seconds of ``exo-bench equations`` for ``mech`` in ``fmt`` (latex, python, c, casadi)."""
    return _loglog(list(EQUATIONS_POINTS[fmt][mech.dim]), float(mech.nlinks))
