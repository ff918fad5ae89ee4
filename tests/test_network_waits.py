"""Every network wait has a timeout, and a peer that is not a Dask scheduler gets one clear line
(issue 34: H2).

The peers are socket servers in a thread of this process on 127.0.0.1 (loopback only): one accepts and
never speaks, the others answer with bytes that are not Dask's protocol (an HTTP server's reply
among them: its first 8 bytes, read as a frame length, asked for 3.07 EiB). The silent peer's wait
ends by the injected timeout (half a second), never by the test's own clock.
"""

from __future__ import annotations

import contextlib
import os
import socket
import threading

import pytest
from cli_runs import cli_process

from exo_bench.bench.cluster import cluster as cluster_mod


@contextlib.contextmanager
def peer(reply: bytes | None):
    """A server on 127.0.0.1 that accepts every connection and sends ``reply``, then closes it (None:
    holds it open and sends nothing, ever); yields its ``tcp://`` address."""
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.bind(("127.0.0.1", 0))
    srv.listen(16)
    conns: list[socket.socket] = []
    stop = threading.Event()

    def serve():
        while not stop.is_set():
            try:
                c, _ = srv.accept()
            except OSError:
                return
            if reply is None:
                conns.append(c)  # held open, silent
                continue
            with contextlib.suppress(OSError):
                c.sendall(reply)
            c.close()  # said its piece, as an HTTP server would

    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield f"tcp://127.0.0.1:{srv.getsockname()[1]}"
    finally:
        stop.set()
        srv.close()
        for c in conns:
            c.close()


GARBAGE = {
    "http": b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n",
    "ones": b"\xff" * 64,
    "short": b"hello",
    "zeros": b"\x00" * 64,
}


def _check_in_thread(address: str, timeout: float) -> BaseException | None:
    """``check_scheduler(address, timeout)`` in a thread; its exception (None: it returned). A wait
    that outlives ten minutes (a safety net, never reached: issue 34, F1) fails the test instead of hanging it."""
    box: list[BaseException | None] = [None]

    def run():
        try:
            cluster_mod.check_scheduler(address, timeout=timeout)
        except BaseException as e:  # noqa: BLE001 - handed to the test
            box[0] = e

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(600)
    assert not t.is_alive(), f"check_scheduler({address!r}) still waiting after 600 s (timeout {timeout} s)"
    return box[0]


@pytest.mark.case("H2")
def test_a_silent_peer_is_refused_after_the_timeout_naming_the_address():
    """A ``--scheduler`` peer that accepts and never speaks is refused after the connect timeout, in one
    line naming the address and the timeout (it hung past 180 s)."""
    with peer(None) as address:
        e = _check_in_thread(address, timeout=0.5)
    assert isinstance(e, ValueError), repr(e)
    msg = str(e)
    assert address in msg and "0.5 s" in msg and len(msg.splitlines()) == 1, msg


@pytest.mark.case("H2")
@pytest.mark.parametrize("kind", sorted(GARBAGE))
def test_a_peer_sending_garbage_is_refused_in_one_line_naming_the_address(kind):
    """A peer that answers with bytes that are not Dask's protocol is refused with one line naming the
    address (an HTTP reply gave "Unable to allocate 3.07 EiB")."""
    with peer(GARBAGE[kind]) as address:
        e = _check_in_thread(address, timeout=30.0)
    assert isinstance(e, ValueError), repr(e)
    msg = str(e)
    assert address in msg and "not a Dask scheduler" in msg and len(msg.splitlines()) == 1, msg
    assert "EiB" not in msg and "allocate" not in msg, msg


@pytest.mark.case("H2")
def test_the_cli_takes_the_timeout_from_dasks_connect_setting(tmp_path):
    """``exo-bench bench --scheduler`` at a silent peer ends after ``distributed.comm.timeouts.connect``
    (here 0.5 s, from the environment), in one line naming the address, exit 2."""
    with peer(None) as address:
        r = cli_process(
            "bench",
            "--scheduler",
            address,
            "--reports",
            tmp_path,
            timeout=1800,
            env={**os.environ, "DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "0.5"},
        )
    err = r.stderr.strip()
    assert r.returncode == 2 and len(err.splitlines()) == 1, err
    assert address in err and "0.5 s" in err, err


def test_the_timeout_is_the_smaller_of_ours_and_dasks():
    """The connect timeout is dask's ``distributed.comm.timeouts.connect`` when smaller than
    :data:`SCHEDULER_TIMEOUT`, else ours."""
    import dask

    with dask.config.set({"distributed.comm.timeouts.connect": "250ms"}):
        assert cluster_mod.scheduler_timeout() == 0.25
    with dask.config.set({"distributed.comm.timeouts.connect": "1h"}):
        assert cluster_mod.scheduler_timeout() == cluster_mod.SCHEDULER_TIMEOUT
