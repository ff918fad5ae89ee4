"""Time budgets for the symbolic work: a skip with a reason instead of a hang.

Every entry point of :mod:`lagrange` takes ``budget`` (seconds) and runs its work inside
:func:`time_budget`. Two mechanisms stop the work:

* **SIGALRM** (``signal.setitimer``), armed only in the main thread and only while the budget is
  open (the previous handler is restored on exit), interrupts any pure-Python sympy call
  (expansion, ``lambdify``, ``cse``) when the budget runs out; :func:`without_interrupts` (the
  ``interrupt=False`` option of a prepared Lagrange model) turns it off;
* **cooperative checks**: the derivation's own loops call :meth:`Deadline.check` per point mass,
  per coordinate and per equation. Outside the main thread (where a signal cannot be armed) these
  checks are the only stop, so a single long sympy call there (a large ``lambdify``) can
  overrun the budget until it returns; the check right after it then raises.

Either way the caller gets :class:`BudgetExceeded`, whose ``skip_reason`` names the work, the
model size (``n``, ``dim``) and the budget, so :func:`exo_bench.bench.studies.study.run_methods` records a skip.
Nested budgets (``inverse_dynamics`` calling ``derive``) share the tighter end.

The clock is injectable: :func:`budget_clock` (for this thread) or ``time_budget(..., clock=...)``
replaces ``time.perf_counter`` by any function returning seconds, for example one that advances a
fixed step per reading, so that a test makes a budget fire (or not) at a known cooperative check,
whatever the machine's speed. Under an injected clock no SIGALRM is armed (the alarm counts real
seconds): the cooperative checks are the only stop. Users keep the real clock and the alarm.
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

#: Seconds since an arbitrary origin; ``time.perf_counter`` unless a test injects another.
Clock = Callable[[], float]


class BudgetExceeded(ValueError):
    """The symbolic work did not finish within its time budget (a ValueError: the model is too
    large for the budget the caller gave).

    ``skip_reason`` is one line naming the work, ``n``, ``dim`` and the budget.
    """

    def __init__(self, what: str, nlinks: int, dim: int, budget: float, elapsed: float | None = None, note: str = ""):
        self.what, self.nlinks, self.dim, self.budget, self.elapsed = what, nlinks, dim, budget, elapsed
        took = f" (stopped after {elapsed:.2f} s)" if elapsed is not None else ""
        self.skip_reason = (
            f"{what} for n={nlinks} links, dim={dim} exceeded the time budget of {budget:g} s{took}{note}"
        )
        super().__init__(self.skip_reason)


class BudgetAlarm(BaseException):
    """Raised by the SIGALRM handler and turned into :class:`BudgetExceeded` where the budget was
    opened; a BaseException so that no ``except Exception`` in sympy swallows it on its way out.
    Catch it only to clean up and re-raise."""


@dataclass
class Deadline:
    """The end of a budget, checked cooperatively with :meth:`check`, read on ``clock``."""

    what: str
    nlinks: int
    dim: int
    budget: float
    start: float = math.nan  # nan: the clock's reading when the deadline is made
    end: float = 0.0
    interrupts: bool = False  # True when SIGALRM is armed for this deadline
    clock: Clock = time.perf_counter

    def __post_init__(self) -> None:
        if math.isnan(self.start):
            self.start = self.clock()
        self.end = self.start + self.budget

    @property
    def remaining(self) -> float:
        return self.end - self.clock()

    @property
    def elapsed(self) -> float:
        """Seconds on this deadline's clock since it started."""
        return self.clock() - self.start

    def exceeded(self, note: str = "") -> BudgetExceeded:
        return BudgetExceeded(self.what, self.nlinks, self.dim, self.budget, self.elapsed, note)

    def check(self) -> None:
        if self.clock() > self.end:
            raise self.exceeded()


_active = threading.local()


@contextmanager
def _thread_setting(name: str, value: object, default: object) -> Iterator[None]:
    """This thread's setting ``name`` is ``value`` within the block, and what it was after it."""
    before = getattr(_active, name, default)
    setattr(_active, name, value)
    try:
        yield
    finally:
        setattr(_active, name, before)


@contextmanager
def without_interrupts():
    """Within this block, budgets use only their cooperative checks: no SIGALRM handler is
    installed, even in the main thread (for callers that own the signal, or that run an event
    loop). A single long sympy call can then overrun the budget until it returns."""
    with _thread_setting("no_signals", True, default=False):
        yield


@contextmanager
def budget_clock(clock: Clock) -> Iterator[None]:
    """Within this block, this thread's budgets read ``clock`` instead of ``time.perf_counter``
    and arm no SIGALRM: a deterministic stand-in for the wall clock (tests), e.g. one that
    advances a fixed step per reading."""
    with _thread_setting("clock", clock, default=None):
        yield


def current_deadline() -> Deadline | None:
    """The innermost active deadline of this thread, if any."""
    stack = getattr(_active, "stack", None)
    return stack[-1] if stack else None


@contextmanager
def time_budget(budget: float, what: str, nlinks: int, dim: int, clock: Clock | None = None) -> Iterator[Deadline]:
    """Run the body within ``budget`` seconds or raise :class:`BudgetExceeded`.

    Yields the :class:`Deadline` to check cooperatively. Inside an enclosing budget the tighter
    of the two ends applies, and the exception names the enclosing work when that one runs out.
    ``clock`` (default: the one of :func:`budget_clock`, else the enclosing budget's, else
    ``time.perf_counter``) reads the seconds; any clock but ``time.perf_counter`` arms no SIGALRM.
    """
    if not 0 < budget < float("inf"):
        raise ValueError(f"{what}: field 'budget': expected a positive, finite number of seconds, got {budget!r}")
    outer = current_deadline()
    clock = clock or getattr(_active, "clock", None) or (outer.clock if outer is not None else time.perf_counter)
    dl = Deadline(what, nlinks, dim, float(budget), clock=clock)
    if outer is not None and outer.clock is clock and outer.end < dl.end:
        # The enclosing budget ends first: it is the one that is exceeded.
        dl = Deadline(outer.what, outer.nlinks, outer.dim, outer.budget, start=outer.start, clock=clock)
    main = (
        clock is time.perf_counter
        and threading.current_thread() is threading.main_thread()
        and hasattr(signal, "setitimer")
        and not getattr(_active, "no_signals", False)
    )
    old_handler = None
    old_remaining = 0.0
    if main:
        old_remaining = signal.getitimer(signal.ITIMER_REAL)[0]
        armed_at = time.perf_counter()
        prev = signal.getsignal(signal.SIGALRM)

        def handler(signum, frame):
            if not dl.interrupts:
                return
            now = time.perf_counter()
            if now >= dl.end - 1e-3:
                raise BudgetAlarm()
            if 0 < old_remaining <= now - armed_at + 1e-3 and callable(prev):
                prev(signum, frame)  # an enclosing, foreign timer ran out: hand it over
                return
            signal.setitimer(signal.ITIMER_REAL, max(dl.end - now, 1e-4))  # early: wait on

        old_handler = signal.signal(signal.SIGALRM, handler)
        dl.interrupts = True
        first = dl.remaining if old_remaining <= 0 else min(dl.remaining, old_remaining)
        signal.setitimer(signal.ITIMER_REAL, max(first, 1e-4))
    stack = getattr(_active, "stack", None)
    if stack is None:
        stack = _active.stack = []
    stack.append(dl)
    try:
        yield dl
    except BudgetAlarm:
        raise dl.exceeded() from None
    finally:
        dl.interrupts = False
        stack.pop()
        if main:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old_handler)
            if old_remaining > 0:  # re-arm the enclosing timer with what is left of it
                left = old_remaining - (time.perf_counter() - armed_at)
                signal.setitimer(signal.ITIMER_REAL, max(left, 1e-4))
