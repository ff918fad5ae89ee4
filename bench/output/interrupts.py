"""How a command's work ends early: SIGINT and SIGTERM while it runs (every interrupt is reported, none
is lost), and a numerical solve that ends without a solution (:class:`SolveFailed`, one line, exit 2).

The command line installs one :class:`Interrupts` handler for both signals (:func:`installed`). It
records the signal, then raises ``KeyboardInterrupt`` as Python's own Ctrl-C handler does, so that
the work stops where it is and the staging folder is removed. Python cannot propagate an exception
raised inside a garbage-collection callback, a finaliser (``__del__``) or a weakref callback: it
prints "Exception ignored in ..." and goes on, so a signal that landed there was lost and the run
finished with exit 0 (issue 34, T1); there the handler only records it (:func:`cannot_propagate`),
and the callback runs to its end. A solver that polls for Ctrl-C (CasADi's IPOPT) turns the
interrupt into its own failure ("IPOPT did not solve", U3). The record survives both: :func:`check` raises
``KeyboardInterrupt`` again at the commands' safe points (before each scene and before publishing,
after each sweep row, after a failed solve, and when the command returns), so the command ends as
interrupted (exit 130) and nothing is published after the signal. While installed, the unraisable
hook keeps Python's report of the swallowed ``KeyboardInterrupt`` off stderr: the command's one line
says "interrupted".

The record is the handler object itself (``signal.getsignal``), so nothing module-level changes.
"""

from __future__ import annotations

import contextlib
import gc
import signal
import sys
import weakref
from collections.abc import Iterator
from types import FrameType


SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Interrupts:
    """The handler of SIGINT and SIGTERM while a command runs: records the signal, then raises
    ``KeyboardInterrupt`` (module docstring)."""

    def __init__(self) -> None:
        self.signum: int | None = None

    def __call__(self, signum: int, frame: FrameType | None) -> None:
        self.signum = signum
        if not cannot_propagate(frame):  # there, the next safe point raises it (check)
            raise KeyboardInterrupt


def cannot_propagate(frame: FrameType | None) -> bool:
    """The interrupted code runs where Python drops an exception: a finaliser (``__del__``), a
    garbage-collection callback (``gc.callbacks``) or a ``weakref.finalize`` callback. Raising there
    would only cut the callback short."""
    callbacks = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        code = frame.f_code
        if code.co_name == "__del__" or code in callbacks or code is _FINALIZE_CALL:
            return True
        frame = frame.f_back
    return False


_FINALIZE_CALL = weakref.finalize.__call__.__code__


def pending() -> int | None:
    """The signal an installed :class:`Interrupts` received (None: none, or none installed)."""
    for s in SIGNALS:
        h = signal.getsignal(s)
        if isinstance(h, Interrupts) and h.signum is not None:
            return h.signum
    return None


def check() -> None:
    """A safe point: raise ``KeyboardInterrupt`` if a signal was received, even one whose own
    ``KeyboardInterrupt`` was swallowed where it landed."""
    if pending() is not None:
        raise KeyboardInterrupt


@contextlib.contextmanager
def installed() -> Iterator[Interrupts | None]:
    """One :class:`Interrupts` for SIGINT and SIGTERM, and the unraisable hook that keeps a swallowed
    interrupt's report off stderr; the previous handlers and hook are put back on exit. Outside the
    main thread (where handlers cannot be set) nothing is installed and None is yielded."""
    handler = Interrupts()
    try:  # a signal the process was started to ignore (nohup, a background job) stays ignored
        previous = {s: signal.signal(s, handler) for s in SIGNALS if signal.getsignal(s) is not signal.SIG_IGN}
    except ValueError:  # not the main thread
        yield None
        return
    hook = sys.unraisablehook

    def quiet(unraisable) -> None:
        if handler.signum is not None and isinstance(unraisable.exc_value, KeyboardInterrupt):
            return  # reported as "interrupted" at the next safe point
        hook(unraisable)

    sys.unraisablehook = quiet
    try:
        yield handler
    finally:
        sys.unraisablehook = hook
        for s, h in previous.items():
            signal.signal(s, signal.SIG_DFL if h is None else h)  # None: a handler set from C


# The one exception of a numerical solve that ends without a solution (IPOPT in the step's and the stride's
# problems): the command line's one handler (bench/cli/app.py ``error_line``) prints it as one line, exit 2, and
# nothing is written. A RuntimeError of any other cause stays an internal error.


class SolveFailed(RuntimeError):
    """A solver stopped without a solution; ``stats`` holds what it reported (status, iterations)."""

    def __init__(self, message: str, stats: dict | None = None) -> None:
        super().__init__(message)
        self.stats = dict(stats or {})
