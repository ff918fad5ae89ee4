"""What a run may take of the machine: its memory, its counts of threads and processes, and memos that
never grow without bound.

**Memory of a run**: the chunk length that keeps a chunk's temporaries near :data:`CHUNK_BYTES`, and the
memory the machine can give (:func:`available_memory`) and a run may plan to use (:func:`usable_memory`).

**Bounded memos.** A memo keyed on user input holds at most a fixed number of entries (issue 34; the guide: "no module
globals that mutate" and a long-running process that prepares many mechanisms must not grow without
bound).

:class:`BoundedCache` is a dict that forgets its least recently stored or read entry beyond
``maxsize``: the module-level memos of derivations and compiled functions keyed on a mechanism
(lagrange/derivation.py, lagrange/numeric.py, bench/perf/peers.py) are instances of it. Memos of
constants (a kernel, a class's type hints) stay ``functools.cache``.

**Counts.** The bound of every count of threads or processes a user sets, and the address space their stacks need.

A user sets three counts: Pinocchio's ``threads`` (``prepare(mech, "pinocchio", threads=N)``, OpenMP
threads of ``rneaInParallel``), ``--workers`` (the local Dask cluster's worker processes) and
``NUMBA_NUM_THREADS`` (numba's threads). Each is a whole number from 1 to :func:`max_count`:
:data:`PER_CPU` per CPU this process may run on. Why a multiple of the CPUs and not a fixed number:
threads and processes beyond the cores only take turns on them (the most any measurement here found
useful is two per core: bench/test_inverse_dynamics.py tries 2, the CPUs and twice the CPUs), while
each adds its stack, its scratch (a Pinocchio ``Data`` per thread) or a whole process; four per CPU
leaves room for hyper-threads and waits and refuses the typo (1000 threads on two cores ran the
process out of address space, and libgomp ended it with no exception: issue 34, C1).

Within the bound, the count must also fit under the user's process limit (RLIMIT_NPROC, ``ulimit -u``,
which counts threads too): :func:`task_room`. Within both, what the count creates is predicted before
it is created: the threads' stacks and scratch against the address space left under ``ulimit -v`` (:func:`check_thread_room`; the stacks are
reserved whole, whether or not they are touched), a Pinocchio ``Data`` per thread against the memory
(:mod:`exo_bench.api.cost_model`), and :data:`WORKER_BYTES` per local worker (``--workers``).
"""

from __future__ import annotations

import os
import resource
from collections import OrderedDict
from typing import TypeVar

#: Threads or processes per usable CPU (module docstring).
PER_CPU = 4
#: The stack of a thread when neither ``OMP_STACKSIZE`` nor the stack limit says (glibc's default
#: follows ``ulimit -s``, 8 MiB on most systems).
DEFAULT_STACK = 8 * 2**20
#: Memory of one local Dask worker (``--workers``): its process (65 MB measured, distributed 2026.8)
#: and the pytest process it runs a benchmark row in (190 MB with numpy, numba, Pinocchio and the
#: package imported), rounded up; the row's own work is estimated by its own tests.
WORKER_BYTES = 256 * 2**20
#: Threads and processes one local Dask worker adds (RLIMIT_NPROC counts both): its process's 3 threads
#: (measured, distributed 2026.8, threads_per_worker=1) and at least one for its row's pytest process.
WORKER_TASKS = 4
#: Threads a local cluster adds in this process (its scheduler and client: 7 measured), rounded up.
CLUSTER_TASKS = 8


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def max_count() -> int:
    """The largest count of threads or worker processes a user may set: :data:`PER_CPU` per usable CPU."""
    return PER_CPU * usable_cpus()


def count_problem(value: object, what: str = "threads") -> str | None:
    """Why ``value`` is not a count of ``what`` from 1 to :func:`max_count` (None: it is)."""
    bound = max_count()
    ok_type = isinstance(value, int) and not isinstance(value, bool)
    if not ok_type:
        try:
            import numpy as np

            ok_type = isinstance(value, np.integer)
        except ImportError:  # pragma: no cover - numpy is a dependency
            pass
    if ok_type and 1 <= int(value) <= bound:  # type: ignore[call-overload]
        room = task_room()
        if room is None or int(value) <= room:  # type: ignore[call-overload]
            return None
        return (
            f"expected at most {room} {what}: this user may start {room} more threads or processes under its "
            f"process limit (RLIMIT_NPROC, ulimit -u {resource.getrlimit(resource.RLIMIT_NPROC)[0]}, "
            f"threads included), got {value!r}"
        )
    return (
        f"expected a whole number of {what} from 1 to at most {bound} ({PER_CPU} per usable CPU, "
        f"{usable_cpus()} here: more only take turns on the cores), got {value!r}"
    )


def user_tasks(uid: int) -> int:
    """Threads of every process of real user ``uid`` (what RLIMIT_NPROC counts), from /proc; 0 where
    /proc cannot be read."""
    total = 0
    try:
        pids = [p for p in os.listdir("/proc") if p.isdigit()]
    except OSError:
        return 0
    for pid in pids:
        try:
            with open(f"/proc/{pid}/status") as f:
                fields = dict(line.split(":", 1) for line in f if ":" in line)
            if int(fields["Uid"].split()[0]) == uid:
                total += int(fields["Threads"])
        except (OSError, ValueError, KeyError):  # a process that ended meanwhile
            continue
    return total


def task_room() -> int | None:
    """Threads or processes this user may still start under RLIMIT_NPROC (``ulimit -u``): the soft limit
    less the user's running threads (:func:`user_tasks`); None when unlimited or not enforced (the kernel
    does not apply it to root)."""
    soft = resource.getrlimit(resource.RLIMIT_NPROC)[0]
    uid = os.getuid()
    if soft in (resource.RLIM_INFINITY, -1) or uid == 0:
        return None
    return max(0, int(soft) - user_tasks(uid))


def check_count(option: str, value: object, what: str = "threads") -> int:
    """``value`` as an int, or a ValueError naming ``option``, the bound and the value."""
    problem = count_problem(value, what)
    if problem:
        raise ValueError(f"{option}: {problem}")
    return int(value)  # type: ignore[call-overload]


def thread_stack_bytes() -> int:
    """Bytes of address space one new thread's stack reserves: ``OMP_STACKSIZE`` (or
    ``GOMP_STACKSIZE``) when set, else the stack limit (``ulimit -s``), else :data:`DEFAULT_STACK`."""
    for var in ("OMP_STACKSIZE", "GOMP_STACKSIZE"):
        size = _omp_size(os.environ.get(var, ""))
        if size:
            return size
    soft = resource.getrlimit(resource.RLIMIT_STACK)[0]
    return int(soft) if soft not in (resource.RLIM_INFINITY, -1) and soft > 0 else DEFAULT_STACK


def _omp_size(text: str) -> int | None:
    """OpenMP's size syntax: a number with an optional B, K (the default), M or G suffix."""
    t = text.strip().upper()
    if not t:
        return None
    unit = {"B": 1, "K": 2**10, "M": 2**20, "G": 2**30}.get(t[-1])
    digits = t[:-1] if unit else t
    try:
        return int(digits) * (unit or 2**10)
    except ValueError:
        return None


def address_space_room() -> int | None:
    """Bytes of address space this process may still map under ``ulimit -v`` (RLIMIT_AS); None when
    unlimited or unknown."""
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    if soft in (resource.RLIM_INFINITY, -1):
        return None
    try:
        with open("/proc/self/statm") as f:
            used = int(f.read().split()[0]) * resource.getpagesize()
    except (OSError, ValueError, IndexError):
        return None
    return max(0, int(soft) - used)


def check_thread_room(option: str, threads: int, scratch_bytes: float = 0.0) -> None:
    """Refuse (ValueError naming ``option``, how many fit and the value) ``threads`` new threads whose
    stacks, and ``scratch_bytes`` of scratch (their Data), do not fit in the address space left under
    ``ulimit -v``."""
    room = address_space_room()
    if room is None:
        return
    stack = thread_stack_bytes()
    need = threads * stack + scratch_bytes
    if need > room:
        per = stack + scratch_bytes / max(threads, 1)
        fits = int(room // per)
        raise ValueError(
            f"{option}: {threads} threads need {_mb(need)} of address space (stacks of {_mb(stack)} each, "
            f"from the stack limit or OMP_STACKSIZE, and their scratch), more than the {_mb(room)} left under this "
            f"process's address-space limit (ulimit -v); expected at most {fits}, got {threads}"
        )


def check_workers(value: object, usable: int | None) -> int:
    """``--workers``: a count from 1 to :func:`max_count` whose processes (:data:`WORKER_BYTES` each) fit
    in ``usable`` bytes (None: unknown, not checked); else a ValueError naming the option."""
    n = check_count("--workers", value, "worker processes")
    if usable is not None and n * WORKER_BYTES > usable:
        fits = max(0, usable // WORKER_BYTES)
        raise ValueError(
            f"--workers: {n} local workers need about {_mb(n * WORKER_BYTES)} of memory ({_mb(WORKER_BYTES)} each: "
            f"the worker process and the pytest process of its row), more than the {_mb(usable)} a run may use; "
            f"expected at most {fits}, got {n}"
        )
    room, need = task_room(), n * WORKER_TASKS + CLUSTER_TASKS
    if room is not None and need > room:
        raise ValueError(
            f"--workers: {n} local workers start about {need} threads and processes ({WORKER_TASKS} per worker, "
            f"{CLUSTER_TASKS} for the cluster in this process), more than the {room} this user may still start "
            f"under its process limit (RLIMIT_NPROC, ulimit -u {resource.getrlimit(resource.RLIMIT_NPROC)[0]}); "
            f"expected at most {max(0, (room - CLUSTER_TASKS) // WORKER_TASKS)}, got {n}"
        )
    return n


def _mb(x: float) -> str:
    return f"{x / 2**30:.1f} GiB" if x >= 2**30 else f"{x / 2**20:.0f} MiB"


#: Target bytes of one chunk's temporaries (see :func:`default_chunk_samples`).
CHUNK_BYTES = 64 * 2**20
#: No chunk is longer than this: past it a longer chunk saves no measurable call overhead.
MAX_CHUNK = 65536


def default_chunk_samples(dof: int, bytes_per_sample: float | None = None) -> int:
    """Samples per chunk so that one chunk's temporaries stay near :data:`CHUNK_BYTES`.

    ``bytes_per_sample`` defaults to a bound for every method: ``8 (dof^2 + 64 dof)`` bytes (the
    matrix family forms ``(samples, n, n)`` matrices, some dozens of them, ``n <= dof / 2``;
    the others keep a few dozen ``(samples, dof)`` arrays)."""
    if bytes_per_sample is None:
        bytes_per_sample = 8.0 * (dof * dof + 64 * dof)
    return int(max(1, min(MAX_CHUNK, CHUNK_BYTES // max(bytes_per_sample, 1.0))))


def available_memory() -> int | None:
    """Bytes that can be allocated without swapping: ``MemAvailable`` of /proc/meminfo, or less
    when a cgroup (container) limit leaves less (``memory.max - memory.current``); elsewhere the
    free physical pages; None where that is unknown."""
    avail = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (OSError, ValueError, AttributeError):
            return None
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            cap = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            used = int(f.read().strip())
        if cap != "max":
            avail = min(avail, max(int(cap) - used, 0))
    except (OSError, ValueError):
        pass
    return avail


#: The share of :func:`available_memory` a run may plan to use by default: the rest is left to
#: the system and to other processes, so that a run that fits its estimate is not killed by the
#: kernel's out-of-memory killer (a 3D chain of 300 links estimated at 23.7 GB, run with 23.9 GB
#: available, was killed).
USABLE_SHARE = 0.8


def usable_memory() -> int | None:
    """The default memory limit: :data:`USABLE_SHARE` of :func:`available_memory` (None if unknown)."""
    avail = available_memory()
    return None if avail is None else int(USABLE_SHARE * avail)


def chunks(S: int, size: int):
    for s0 in range(0, S, size):
        yield slice(s0, min(S, s0 + size))


class CallTooLarge(MemoryError):
    """A call whose estimated memory exceeds what a run may use (:func:`usable_memory`), refused before
    any work (issue 34: memory is predicted before the work, with ``check=False`` too)."""


def batch_samples(q) -> int:
    """The sample count of a batch ``(samples, dof)``, read from its shape without converting it; 0 for
    one sample and for what has no shape (a list holds its memory already)."""
    shape = getattr(q, "shape", None)
    return int(shape[0]) if isinstance(shape, tuple) and len(shape) == 2 else 0


def check_call(source: str, samples: int, dof: int, need: float, what: str, error=CallTooLarge) -> None:
    """Refuse with ``error`` a call of ``samples`` states whose estimated bytes ``need`` exceed
    :func:`usable_memory`; ``what`` says what they hold. Asked only above :data:`CHUNK_BYTES` (every
    batched call allocates one chunk's temporaries unasked; reading /proc/meminfo costs ~0.1 ms)."""
    if need <= CHUNK_BYTES:
        return
    limit = usable_memory()
    if limit is not None and need > limit:
        raise error(
            f"{source}: {samples} samples of {dof} coordinates need about {need / 2**30:.2f} GiB ({what}), "
            f"over the {limit / 2**30:.2f} GiB a run may use; expected fewer samples per call"
        )


def check_batch(source: str, q, dof: int, per_sample: int) -> None:
    """Refuse, before the states are converted, a batch ``q`` whose ``per_sample`` float64 entries per
    sample (the converted states, the result and the work, at most one chunk's) exceed
    :func:`usable_memory`: a few integer multiplications, nothing for one sample."""
    shape = getattr(q, "shape", None)  # batch_samples, inline: one call fewer on every public call
    if isinstance(shape, tuple) and len(shape) == 2 and 8.0 * int(shape[0]) * per_sample > CHUNK_BYTES:
        samples = int(shape[0])
        check_call(source, samples, dof, 8.0 * samples * per_sample, "the states, the result and the work")


K = TypeVar("K")
V = TypeVar("V")


class BoundedCache(OrderedDict[K, V]):
    """An ordered dict of at most ``maxsize`` entries; storing or reading (``[key]``) an entry makes it
    the most recent, and storing beyond ``maxsize`` drops the least recent."""

    def __init__(self, maxsize: int) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"BoundedCache: field 'maxsize': expected an integer >= 1, got {maxsize!r}")
        super().__init__()
        self.maxsize = maxsize

    def __getitem__(self, key: K) -> V:
        value = super().__getitem__(key)
        self.move_to_end(key)
        return value

    def __setitem__(self, key: K, value: V) -> None:
        super().__setitem__(key, value)
        self.move_to_end(key)
        while len(self) > self.maxsize:
            self.popitem(last=False)
