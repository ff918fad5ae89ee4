"""The package's code that changes signal handling puts back what it changed (issue 34, the SIGINT found
ignored in an xdist worker when the Ctrl-C tests ran).

What set it: no code of the package. A command started in the background by a shell without job control
(``cmd &`` in a script, as a job runner starts the suite) starts with SIGINT and SIGQUIT ignored (POSIX:
asynchronous lists), and Python then keeps SIG_IGN as SIGINT's handler; the xdist workers inherit it.
:func:`test_a_background_job_starts_with_sigint_ignored` shows it. Each call below, made without a
fixture, leaves SIGINT's, SIGTERM's and SIGALRM's handlers, the signal mask and the interval timer as
it found them, whatever SIGINT's handler was before (ignored, default, Python's, a custom one).
"""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

WATCHED = (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)


def _state():
    return (
        tuple(signal.getsignal(s) for s in WATCHED),
        signal.pthread_sigmask(signal.SIG_BLOCK, set()),
        signal.getitimer(signal.ITIMER_REAL),
    )


def _custom(signum, frame):  # a handler the caller had installed
    raise KeyboardInterrupt


def _interrupts():
    from exo_bench.bench.output.interrupts import installed

    with installed():
        pass


def _interrupts_raising():
    from exo_bench.bench.output.interrupts import installed

    with pytest.raises(RuntimeError), installed():
        raise RuntimeError("the body failed")


def _budget():
    from exo_bench.lagrange.budget import time_budget

    with time_budget(30.0, "a test", 1, 2) as dl:
        dl.check()


def _signals_held():
    from exo_bench.bench.output.publish import _signals_held

    with _signals_held():
        pass


CALLS = {"interrupts": _interrupts, "interrupts-raising": _interrupts_raising, "budget": _budget, "held": _signals_held}


@pytest.mark.parametrize("before", ["ignored", "default", "python", "custom"])
@pytest.mark.parametrize("call", sorted(CALLS))
def test_the_call_leaves_the_signal_handling_as_it_found_it(call, before):
    handler = {
        "ignored": signal.SIG_IGN,
        "default": signal.SIG_DFL,
        "python": signal.default_int_handler,
        "custom": _custom,
    }[before]
    saved = signal.signal(signal.SIGINT, handler)
    try:
        was = _state()
        CALLS[call]()
        assert _state() == was
    finally:
        signal.signal(signal.SIGINT, saved)


def test_a_background_job_starts_with_sigint_ignored():
    """``sh -c 'python ... &'``: the background Python finds SIGINT ignored (the inherited disposition
    the Ctrl-C tests met in a worker); a foreground one finds Python's own handler. The shell starts with
    SIGINT at its default, so the test holds when the suite itself runs as a background job (then every
    process it starts inherits SIG_IGN: the fresh-clone run of 1cdc5cb started by ``setsid bash -c '... &'``
    failed here)."""
    probe = f"{sys.executable} -c 'import signal; print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN)'"

    def default_sigint() -> None:  # the shell starts as a terminal's would, whatever the suite inherited
        signal.signal(signal.SIGINT, signal.SIG_DFL)

    def run(script: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            ["sh", "-c", script], capture_output=True, text=True, timeout=60, preexec_fn=default_sigint
        )

    bg, fg = run(f"{probe} & wait"), run(probe)
    assert (bg.stdout.strip(), fg.stdout.strip()) == ("True", "False"), (bg, fg)
