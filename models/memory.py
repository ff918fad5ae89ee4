"""Memory of a run: the chunk length that keeps a chunk's temporaries near :data:`CHUNK_BYTES`, and the
memory the machine can give (:func:`available_memory`) and a run may plan to use (:func:`usable_memory`)."""

from __future__ import annotations

import os


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
