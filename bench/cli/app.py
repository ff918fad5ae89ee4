"""``exo-bench``: the command line. Errors print one line on stderr and exit with code 2.

One module per subcommand (:data:`SUBCOMMANDS`), each with ``add_parser``; this package is the
only user of argparse, and builds typed options (:mod:`exo_bench.bench.studies.options`) for the
studies and report jobs.

No traceback reaches the user from any command: bad input, a file that cannot be read or
written, a method over a memory, time or derivation budget, running out of memory, a resource
error of sympy or Pinocchio and anything unforeseen each end in one line on stderr (``main``);
warnings are one line each too. tests/test_fuzz_cli.py drives every subcommand with generated bad
input to hold this, and docs/errors.md lists the messages (checked against the tests).
"""

from __future__ import annotations

import argparse
import sys


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage dump
        raise _UsageError(f"{self.prog}: {message}")


class _UsageError(Exception):
    pass


#: The subcommands, in the order ``exo-bench --help`` lists them: one module each, with its
#: ``add_parser(subparsers)``.
SUBCOMMANDS = (
    "presets",
    "states",
    "inverse",
    "forward",
    "urdf",
    "mjcf",
    "run",
    "bench",
    "errata",
    "stability",
    "equations",
    "gait",
    "stride",
)


def _version() -> str:
    import exo_bench

    return exo_bench.__version__


def build_parser() -> argparse.ArgumentParser:
    import importlib

    from exo_bench.api.methods import method_names

    methods = method_names()  # the method table's, never typed
    p = _Parser(
        prog="exo-bench",
        description="Equations of motion of variable-length rod exoskeletons: "
        f"{len(methods)} methods ({', '.join(methods)}), cross-checked, timed and visualised.",
    )
    p.add_argument("--version", action="version", version=f"exo-bench {_version()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for name in SUBCOMMANDS:
        importlib.import_module(f"exo_bench.bench.cli.{name}").add_parser(sub)
    return p


#: The exit code when stdout's reader went away, as a shell reports a process ended by SIGPIPE (128 + 13).
BROKEN_PIPE = 141

#: The longest line an error prints: a user's value can be huge (a 400-digit integer, a long string).
MAX_LINE = 500


def _one_line(e: BaseException) -> str:
    text = str(e).strip()
    return _shorten(text.splitlines()[0] if text else type(e).__name__)


def _shorten(line: str) -> str:
    if len(line) <= MAX_LINE:
        return line
    cut = len(line) - MAX_LINE + 40
    return f"{line[: MAX_LINE // 2]} ... ({cut} characters left out) ... {line[-(MAX_LINE // 2 - 40) :]}"


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Python warnings as one line each on stderr (no source line, no file name)."""
    print(
        f"exo-bench: warning: {_one_line(message) if isinstance(message, BaseException) else str(message).splitlines()[0]}",
        file=sys.stderr,
    )


def error_line(e: BaseException) -> str:
    """The one line (without the ``exo-bench: error:`` prefix) for an exception that ends a command:
    every budget or resource error names the budget and how to raise it."""
    from exo_bench.api.cost_model import ResourceLimit

    if isinstance(e, ResourceLimit):
        return str(e)
    from exo_bench.models.runtime.prepared import MissingExtra

    if isinstance(e, MissingExtra):  # an engine not installed: the message names the extra; no budget to raise
        return f"{e}; or choose another method (matrix-factored)"
    skip = getattr(e, "skip_reason", None)
    if skip:  # lagrange.BudgetExceeded: the derivation's time budget
        return f"{skip}; raise the budget with --budget SECONDS or choose another method (matrix-factored)"
    if isinstance(e, MemoryError):
        avail = _available()
        if str(e).strip():  # e.g. the Pinocchio backend's check of its Data against the available memory
            return f"out of memory: {_one_line(e)}"
        return (
            f"out of memory: the model or the batch did not fit in the {avail} available (the limit of every "
            "run; estimated beforehand, see --max-memory); try a smaller batch or method matrix-factored"
        )
    if isinstance(e, RecursionError):  # sympy on a very large expression
        return (
            f"the symbolic derivation nested deeper than Python's recursion limit ({sys.getrecursionlimit()}): "
            "the model is too large for method lagrange; choose another method (matrix-factored)"
        )
    if isinstance(e, RuntimeError) and any(k in str(e) for k in ("bad_alloc", "length_error", "Unable to allocate")):
        return (
            f"out of memory in Pinocchio ({_one_line(e)}): the model does not fit in the {_available()} available "
            "(see --max-memory); choose method matrix-factored"
        )
    if isinstance(e, OSError):
        name = e.filename if e.filename is not None else ""
        return f"{name!s}: {e.strerror or _one_line(e)}" if name else (e.strerror or _one_line(e))
    return _one_line(e)


def _solve_failed(e: BaseException) -> bool:
    """Whether ``e`` is a solve that ended without a solution (IPOPT): one line, never an internal error."""
    from exo_bench.bench.output.interrupts import SolveFailed

    return isinstance(e, SolveFailed)


def _available() -> str:
    from exo_bench.models.machine.memory import available_memory

    a = available_memory()
    return "memory" if a is None else f"{a / 1e9:.1f} GB of memory"


def main(argv: list[str] | None = None) -> int:
    """Run one command; SIGTERM ends it as Ctrl-C does (staging folders removed, exit 130), and an
    interrupt swallowed where it landed still ends it so (:mod:`exo_bench.bench.output.interrupts`)."""
    import warnings

    from exo_bench.bench.output import interrupts

    with interrupts.installed():  # outside the main thread: Python's own Ctrl-C handling only
        return _main(argv, warnings)


def _main(argv, warnings) -> int:
    from contextlib import nullcontext, redirect_stdout

    real = sys.stdout is sys.__stdout__ and sys.stdout is not None  # not a test's or a caller's capture
    with redirect_stdout(_NamedStdout(sys.stdout)) if real else nullcontext(), warnings.catch_warnings():
        warnings.showwarning = _show_warning  # one line each, not Python's file:line and source line
        try:
            args = build_parser().parse_args(argv)
            rc = _run(args)
            sys.stdout.flush()  # a reader gone (| head) or a full disk shows here, not after main returned 0
            return rc
        except _UsageError as e:
            print(_shorten(str(e).splitlines()[0] if str(e).strip() else "exo-bench: usage error"), file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print(
                "exo-bench: interrupted; the reports folder holds only whole files of earlier runs or of this one "
                "(summary.md says which)",
                file=sys.stderr,
            )
            return 130
        except BrokenPipeError:  # the reader of stdout went away (| head): the output is cut, never a success
            _silence_stdout()
            print(
                "exo-bench: error: stdout was closed before all the output was written (broken pipe)", file=sys.stderr
            )
            return BROKEN_PIPE
        except (ValueError, OSError, MemoryError, RecursionError) as e:
            if isinstance(e, OSError) and e.filename == "stdout":
                _silence_stdout()  # nothing more to flush at exit
            print(f"exo-bench: error: {_shorten(error_line(e))}", file=sys.stderr)
            return 2
        except Exception as e:  # noqa: BLE001 - never a traceback: budgets and anything unforeseen, one line
            if getattr(e, "skip_reason", None) or isinstance(e, RuntimeError) and "alloc" in str(e) or _solve_failed(e):
                print(f"exo-bench: error: {_shorten(error_line(e))}", file=sys.stderr)
            else:
                print(
                    f"exo-bench: internal error: {type(e).__name__}: {_one_line(e)} (please report it)", file=sys.stderr
                )
            return 2


def _run(args: argparse.Namespace) -> int:
    """The command's exit code; a signal received meanwhile, even one swallowed where it landed (a
    garbage-collection callback, a finaliser, a solver that polls for Ctrl-C), ends it as interrupted."""
    from exo_bench.bench.output.interrupts import check

    try:
        code = int(args.func(args) or 0)
    except Exception:
        check()  # the interrupt, not what it caused, is what ended the command
        raise
    check()
    return code


class _NamedStdout:
    """The process's stdout, whose write errors name it (``stdout: No space left on device``) as a
    file's name the file (bench/output/files.py, :func:`stream_errors`); everything else is stdout's."""

    def __init__(self, stream) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        from exo_bench.bench.output.files import stream_errors

        with stream_errors("stdout"):
            return self._stream.write(text)

    def flush(self) -> None:
        from exo_bench.bench.output.files import stream_errors

        with stream_errors("stdout"):
            self._stream.flush()

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def _silence_stdout() -> None:
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    sys.exit(main())
