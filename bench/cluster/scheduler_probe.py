"""A ``--scheduler`` address, checked before any work: it must answer Dask's handshake and say it is a
scheduler within a timeout (issue 34, H2), else one line names it."""

from __future__ import annotations


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
