"""One lock per reports folder: runs that publish into one folder do it one after the other.

A run's work (scenes, suite reports) goes on in its own staging folder, in parallel with other
runs; only publishing, which reads ``runs.json``, merges the run's rows and files into it and
rewrites ``summary.md``, holds the folder's lock (:func:`reports_lock`), so every publisher sees
what the one before it published and nothing is lost.

The lock is ``fcntl.flock`` on :data:`LOCK_NAME` in the folder: the kernel releases it when its
holder exits, however it exits (``kill -9`` included), so a waiting run never waits for a dead
one. The file is opened with ``O_NOFOLLOW`` and must be a regular file (a planted link, FIFO or
device is refused in one line), is never truncated by a waiter, and is left in place (removing a
lock file races with the runs waiting on it). Its content names the holder (process id, host,
command), for the one line a run prints when it has waited :data:`NOTICE_AFTER_S` seconds.

Written here rather than taken from ``filelock``: the standard library's ``fcntl`` does the
locking; what a library would add (Windows, soft locks) this Linux-only suite does not use, and the
refusal of planted links and the waiting notice are needed either way.
"""

from __future__ import annotations

import errno
import fcntl
import os
import stat
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

#: The lock file in every reports folder (hidden: it is not a report).
LOCK_NAME = ".exo-bench.lock"
#: A run that has waited this long for the lock says so, once.
NOTICE_AFTER_S = 5.0
#: How often a waiting run tries the lock again.
POLL_S = 0.05


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _refused(path: Path, mode: int) -> ValueError:
    from exo_bench.models.files.atomic_files import kind_of

    if stat.S_ISLNK(mode):
        return ValueError(
            f"{path}: is a symlink (to {os.path.realpath(path)!r}); the reports folder's lock file is never "
            "opened through a link (remove it)"
        )
    return ValueError(f"{path}: is {kind_of(mode)}; the reports folder's lock file must be a regular file (remove it)")


def check_lock_file(folder: Path) -> None:
    """Refuse, before any work, what :func:`open_lock_file` would refuse (without making the file)."""
    path = Path(folder) / LOCK_NAME
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as e:
        if e.errno == errno.ENOTDIR:  # the folder is made later, or refused as a folder
            return
        raise ValueError(f"{path}: cannot check the reports folder's lock file ({e.strerror or e})") from None
    if not stat.S_ISREG(mode):
        raise _refused(path, mode)


def open_lock_file(folder: Path) -> int:
    """The descriptor of ``folder``'s lock file, made if missing; never through a link, never a
    FIFO, a device or a folder (a ValueError line names what is there)."""
    path = Path(folder) / LOCK_NAME
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    try:
        fd = os.open(path, flags, 0o666)
    except OSError as e:
        try:
            mode = os.lstat(path).st_mode
        except OSError:
            mode = stat.S_IFREG
        if e.errno in (errno.ELOOP, errno.EISDIR) and not stat.S_ISREG(mode):
            raise _refused(path, mode) from None
        raise ValueError(f"{path}: cannot open the reports folder's lock file ({e.strerror or e})") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise _refused(path, mode)
    return fd


def _holder(fd: int) -> str:
    """What the lock file says about its holder ("process 123 on host (exo-bench run a)"), or ""."""
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", errors="replace").strip()
    except OSError:
        return ""
    return text.splitlines()[0] if text else ""


def _mark_holder(fd: int, command: str) -> None:
    import socket

    line = f"process {os.getpid()} on {socket.gethostname()} ({command})\n".encode("utf-8", errors="replace")
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, line, 0)
    except OSError:  # the mark is informative only; the lock is what counts
        pass


@contextmanager
def reports_lock(
    folder: Path,
    command: str = "",
    *,
    notice_after: float = NOTICE_AFTER_S,
    clock: Callable[[], float] = time.monotonic,
    pause: Callable[[float], None] = time.sleep,
    say: Callable[[str], None] = _stderr,
) -> Iterator[None]:
    """Hold ``folder``'s lock for the block. Waits while another process holds it (Ctrl-C and
    SIGTERM still end the wait) and says so in one line once it has waited ``notice_after``
    seconds of ``clock``; ``pause`` sleeps between tries. Not reentrant: a process takes it once."""
    folder = Path(folder)
    fd = open_lock_file(folder)
    try:
        start, told = clock(), False
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                pass
            if not told and clock() - start >= notice_after:
                holder = _holder(fd) or "another process"
                say(
                    f"exo-bench: waiting for {str(folder / LOCK_NAME)!r}: {holder} is publishing into the same "
                    "reports folder; this run publishes when it is done"
                )
                told = True
            pause(POLL_S)
        _mark_holder(fd, command)
        yield
    finally:
        os.close(fd)  # releases the lock
