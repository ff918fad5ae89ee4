"""Every wait of a sweep on a Dask cluster is bounded (issue 34: "every network wait has a timeout"): a
``--scheduler`` address is probed before any work (:func:`probe_scheduler`), and the futures are collected
with a silence limit.

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


# A ``--scheduler`` address, checked before any work: it must answer Dask's handshake and say it is a scheduler
# within a timeout (issue 34, H2), else one line names it.


def probe_scheduler(address: str, timeout: float) -> None:
    """Refuse, in one line naming ``address``, a peer that is not a Dask scheduler answering within
    ``timeout`` seconds: connect, complete Dask's handshake and ask its identity, all under one deadline.

    distributed's own ``connect`` bounds only the TCP connection: its handshake read has no timeout,
    so a peer that accepted and never spoke held ``Client(..., timeout=10)`` past 180 s; and a peer
    that spoke another protocol had its first 8 bytes read as a frame length (an HTTP reply asked for
    3.07 EiB)."""
    import asyncio

    from distributed.comm import connect, parse_address
    from distributed.comm.addressing import parse_host_port
    from distributed.comm.registry import backends

    try:
        scheme, loc = parse_address(address)
        if scheme not in backends:
            raise ValueError(f"unknown protocol {scheme!r}")
        if scheme in ("tcp", "tls"):
            parse_host_port(loc)
    except ValueError as e:
        raise ValueError(
            f"--scheduler {address!r}: no Dask scheduler reachable there: expected an address such as "
            f"tcp://10.0.0.1:8786 ({_first_line(e)})"
        ) from None

    async def identity():
        comm = await connect(address, timeout=timeout)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    late = (
        f"--scheduler {address!r}: no Dask scheduler reachable there: nothing answered within {timeout:g} s (nothing "
        "listening, or a peer that does not speak; dask's distributed.comm.timeouts.connect sets the limit)"
    )
    try:
        info = asyncio.run(asyncio.wait_for(identity(), timeout))
    except TimeoutError:
        raise ValueError(late) from None
    except Exception as e:  # noqa: BLE001 - a peer's bytes decoded as Dask's frames: anything can fail
        if isinstance(e, OSError) and "Timed out trying to connect" in str(e):
            raise ValueError(late) from None
        raise ValueError(
            f"--scheduler {address!r}: the peer there is not a Dask scheduler: what it sent is not Dask's protocol"
            + (" (it closed the connection)" if isinstance(e, OSError) else "")
        ) from None
    kind = info.get("type") if isinstance(info, dict) else None
    if kind != "Scheduler":
        raise ValueError(
            f"--scheduler {address!r}: the peer there is not a Dask scheduler (it answered as {kind or 'something else'!r})"
        )


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0][:200] if text else type(e).__name__


__all__ = ["PART_SILENCE", "START_SLACK", "check_silence", "completed", "sweep_silence"]
