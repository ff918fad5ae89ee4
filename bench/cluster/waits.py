"""Every wait of a sweep on a Dask cluster is bounded (issue 34: "every network wait has a timeout").

:func:`completed` replaces ``distributed.as_completed`` where the sweep collects its rows and the
stability study its parts: it yields each future as it finishes, and when none finishes within
``silence`` seconds (a scheduler or its workers that stopped answering) raises one TimeoutError
(an OSError: the command line prints it as one line, exit 2; the finished rows' checkpoints stay).
The bound is a silence, not a total: a long sweep whose rows keep finishing never times out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator

#: Seconds a worker may take to start a row's process (imports, numba's cache) beyond the row's budget.
START_SLACK = 300.0
#: Default silence bound of the stability study's parts (ClusterOptions.wait_timeout): its largest
#: part, the quick profile's forward study, takes minutes; the full one's under an hour on one core.
PART_SILENCE = 3 * 3600.0


def sweep_silence(row_budget: float, retries: int) -> float:
    """The longest a sweep may wait for its next row: a row ends within its budget on each try
    (the worker kills its pytest at the budget), plus :data:`START_SLACK`."""
    return (retries + 1) * row_budget + START_SLACK


def check_silence(silence: object, option: str) -> float:
    """``silence`` as a float, or a ValueError naming ``option``."""
    ok = isinstance(silence, int | float) and not isinstance(silence, bool)
    if not ok or not math.isfinite(float(silence)) or float(silence) <= 0:  # type: ignore[arg-type]
        raise ValueError(f"{option}: expected a finite number of seconds > 0, got {silence!r}")
    return float(silence)  # type: ignore[arg-type]


def completed(
    futures: Iterable, silence: float, *, wait=None, what: str = "tasks", option: str = "wait_timeout"
) -> Iterator:
    """Each of ``futures`` as it finishes; a TimeoutError naming ``what``, the bound and ``option``
    when none of those still running finishes within ``silence`` seconds. ``wait``: a stand-in for
    ``distributed.wait`` (tests)."""
    silence = check_silence(silence, option)
    if wait is None:
        from distributed import wait
    pending = set(futures)
    while pending:
        try:
            done, pending = wait(pending, timeout=silence, return_when="FIRST_COMPLETED")
        except TimeoutError:
            done = set()
        if not done:
            raise TimeoutError(
                f"{what}: none of the {len(pending)} still running finished within {silence:g} s (the scheduler "
                f"or its workers stopped answering?); the finished ones are kept; raise the bound with {option}"
            )
        yield from done


__all__ = ["PART_SILENCE", "START_SLACK", "check_silence", "completed", "sweep_silence"]
