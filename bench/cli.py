"""``exo-bench``: the command line. Errors print one line on stderr and exit with code 2.

No traceback reaches the user from any command: bad input, a file that cannot be read or
written, a method over a memory, time or derivation budget, running out of memory, a resource
error of sympy or Pinocchio and anything unforeseen each end in one line on stderr (``main``);
warnings are one line each too. tests/test_fuzz_cli.py drives every subcommand with generated bad
input to hold this, and docs/errors.md lists the messages (checked against the tests).
"""

from __future__ import annotations

import argparse
import json
import sys

from pathlib import Path

import numpy as np


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage dump
        raise _UsageError(f"{self.prog}: {message}")


class _UsageError(Exception):
    pass


def _load_states(path: str, mech, third: str = "qdd") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The states of a JSON file ``{"q": [[...]], "qd": ..., "qdd": ...}`` or, for large batches, a
    NumPy ``.npz`` archive with arrays ``q``, ``qd``, ``qdd``; validated (names the file).
    ``third="tau"``: forward dynamics' states ``q``, ``qd``, ``tau``."""
    from exo_bench.models.loading import read_json
    from exo_bench.models.mechanism import as_states

    what = f"states {path!r}"
    if str(path).endswith(".npz"):
        data = _read_npz(path, what)
    else:
        data = read_json(path, what)
    if not isinstance(data, dict) or not {"q", "qd", third} <= data.keys():
        got = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise ValueError(f"{what}: expected an object with keys ['q', 'qd', '{third}'], got {got}")
    try:
        return as_states(mech, data["q"], data["qd"], data[third], source=what)
    except ValueError as e:   # as_states calls its third array qdd
        raise ValueError(str(e).replace("field 'qdd'", f"field '{third}'").replace("qdd must", f"{third} must")) from None


def _read_npz(path: str, what: str) -> dict:
    import zipfile

    from exo_bench.models.loading import regular_file
    from exo_bench.models.prepared import usable_memory

    p = regular_file(path, what)   # the same checks and messages as every other file we read
    try:
        with zipfile.ZipFile(p) as zf:
            size = sum(i.file_size for i in zf.infolist())
    except (zipfile.BadZipFile, EOFError, OSError) as e:
        raise ValueError(f"{what}: expected a NumPy .npz archive, got a file that is not one ({e})") from None
    limit = usable_memory()
    if limit is not None and size > limit:
        raise ValueError(f"{what}: its arrays take {size / 1e9:.1f} GB, more than the {limit / 1e9:.1f} GB a run may "
                         "use (--max-memory does not raise this); split the batch")
    try:
        with np.load(p, allow_pickle=False) as z:
            return {k: (z[k] if k in ("q", "qd", "qdd", "tau") else None) for k in z.files}
    except (zipfile.BadZipFile, EOFError) as e:
        raise ValueError(f"{what}: expected a NumPy .npz archive, got a file that is not one ({e})") from None
    except ValueError as e:
        raise ValueError(f"{what}: cannot read the arrays: {str(e).splitlines()[0]}") from None
    except OSError as e:
        raise ValueError(f"{what}: cannot read: {e.strerror or e}") from None


def _limits(args, method: str):
    from exo_bench.bench.resources import Limits

    return Limits(memory=getattr(args, "max_memory", None), seconds=getattr(args, "max_time", None),
                  budget=getattr(args, "budget", None) if method == "lagrange" else None)


def _write_tau(method: str, tau: np.ndarray, out, key: str = "tau") -> None:
    """``{"method": ..., "tau": [[...], ...]}`` (or ``key``) written row block by row block (no list of
    the whole batch is built); non-finite values are null (JSON has no NaN)."""
    out.write(json.dumps({"method": method})[:-1] + f', "{key}": [')
    for s0 in range(0, tau.shape[0], 4096):
        block = tau[s0:s0 + 4096]
        rows = [[None if not np.isfinite(x) else float(x) for x in row] for row in block]
        text = json.dumps(rows, allow_nan=False)[1:-1]
        out.write((", " if s0 else "") + text)
    out.write("]}\n")


def cmd_presets(args) -> int:
    from exo_bench.models.presets import preset_descriptions

    for name, desc in preset_descriptions().items():
        print(f"{name:10s} {desc}")
    return 0


def known_wrong_warning(method: str, dim: int) -> str | None:
    """The one-line warning that every CLI result of a method known to be wrong carries."""
    from exo_bench.bench.methods import KNOWN_WRONG

    if method not in KNOWN_WRONG:
        return None
    if dim == 3:
        return f"exo-bench: warning: method {method!r}: {KNOWN_WRONG[method]}"
    return (f"exo-bench: warning: method {method!r} is eq. (18) exactly as printed, kept to expose the paper's "
            "misprints: wrong in 3D by design; this 2D result is the closed forms (reports/errata.md)")


def _refuse_budget(args) -> None:
    """``--budget`` is lagrange's derivation budget: with another method it would be silently ignored."""
    if args.budget is not None and args.method != "lagrange":
        raise ValueError(f"--budget: the derivation budget of method lagrange; method {args.method!r} derives "
                         "nothing (limit its time with --max-time)")


def cmd_forward(args) -> int:
    """Forward dynamics: the accelerations ``qdd`` of states ``q, qd, tau``; a singular configuration
    is one line naming the sample, the link and the reason (exit 2), never NaN."""
    from exo_bench.bench.methods import method_class, prepare
    from exo_bench.bench.resources import check
    from exo_bench.models.loading import load_mechanism

    method_class(args.method)  # an unknown method fails before any file is read
    _refuse_budget(args)
    mech = load_mechanism(args.mechanism)
    q, qd, tau = _load_states(args.states, mech, third="tau")
    options = {"budget": args.budget} if args.method == "lagrange" and args.budget is not None else {}
    # forward dynamics forms M: dof + 2 inverse-dynamics rows per sample for the methods without their own
    rows = q.shape[0] * (1 if args.method == "newton-euler" else mech.dof + 2)
    check(mech, args.method, rows, options, _limits(args, args.method))   # refuse before any work
    model = prepare(mech, args.method, **options)
    warn = known_wrong_warning(args.method, mech.dim)
    if warn:
        print(warn, file=sys.stderr)
    model.check_regular(q)                    # singular configurations: named, before any work
    qdd = np.asarray(model.forward_dynamics(q, qd, tau, check=False), dtype=float)   # validated above
    _write_tau(args.method, qdd, sys.stdout, key="qdd")
    return 0


def cmd_inverse(args) -> int:
    from exo_bench.bench.methods import method_class, prepare
    from exo_bench.bench.resources import check
    from exo_bench.models.loading import load_mechanism
    from exo_bench.models.mechanism import force_names

    method_class(args.method)  # an unknown method fails before any file is read
    _refuse_budget(args)
    mech = load_mechanism(args.mechanism)
    options = {"budget": args.budget} if args.method == "lagrange" and args.budget is not None else {}
    limits = _limits(args, args.method)
    # reading and writing count in the estimate; a .npz by its uncompressed arrays, from its headers
    from exo_bench.bench.resources import check_reading
    from exo_bench.bench.states_input import peek_states
    peek = peek_states(args.states, mech.dof)
    if peek.samples is not None:
        check(mech, args.method, peek.samples, options, limits, io=peek.io(mech.dof))   # before decompressing
    else:
        check_reading(args.states, peek.read_bytes, peek.read_seconds, limits)
    q, qd, qdd = _load_states(args.states, mech)
    check(mech, args.method, q.shape[0], options, limits, io=peek.io(mech.dof, q.shape[0]))   # before any work
    model = prepare(mech, args.method, **options)
    tau = np.asarray(model.inverse_dynamics(q, qd, qdd, check=False), dtype=float)   # validated above
    warn = known_wrong_warning(args.method, mech.dim)
    if warn:
        print(warn, file=sys.stderr)
    count, first = 0, None
    for s0 in range(0, tau.shape[0], 65536):   # in row blocks: no (samples, dof) mask
        bad = ~np.isfinite(tau[s0:s0 + 65536])
        if bad.any():
            count += int(bad.sum())
            if first is None:
                s, c = map(int, np.argwhere(bad)[0])
                first = (s0 + s, c)
    if count:  # JSON has no NaN: write null, and say so on stderr (never a silent NaN)
        print(f"exo-bench: warning: method {args.method!r} gave {count} NaN/Inf value(s), written as null "
              f"(first: sample {first[0]}, {force_names(mech)[first[1]]})", file=sys.stderr)
    _write_tau(args.method, tau, sys.stdout)
    return 0


def cmd_urdf(args) -> int:
    from exo_bench.models.loading import load_mechanism
    from exo_bench.models.urdf import to_urdf

    if args.output:   # refused before any work when it names a FIFO, a device, a socket (bench/output_files.py)
        from exo_bench.bench.output_files import output_target
        output_target(args.output, "urdf -o")
    text = to_urdf(load_mechanism(args.mechanism))
    if args.output:
        from exo_bench.bench.reporting import atomic_write
        atomic_write(args.output, text)
    else:
        sys.stdout.write(text)
    return 0


def cmd_mjcf(args) -> int:
    """The MJCF of a mechanism, compiled by MuJoCo before it is written (so that a file written loads
    in MuJoCo); ``--no-check`` writes it without MuJoCo."""
    from exo_bench.models.loading import load_mechanism
    from exo_bench.models.mjcf import to_mjcf

    mech = load_mechanism(args.mechanism)
    if args.output:
        from exo_bench.bench.output_files import output_target
        from exo_bench.bench.reporting import writable_folder
        output_target(args.output, "mjcf -o")   # never a FIFO, a device, a socket (bench/output_files.py)
        writable_folder(Path(args.output).resolve().parent, "-o")
    text = to_mjcf(mech)
    if not args.no_check:
        from exo_bench.models.mujoco_backend import compile_mjcf
        compile_mjcf(text, f"MJCF of {mech.name!r}")     # ValueError: MuJoCo missing, or refusing the file
    if args.output:
        from exo_bench.bench.reporting import atomic_write
        atomic_write(args.output, text)
    else:
        sys.stdout.write(text)
    return 0


def reports_folder(value: str | None) -> str | None:
    """``--reports``: a usable folder (:func:`reporting.writable_folder`), checked before any work starts."""
    from exo_bench.bench.reporting import writable_folder

    if value is None:
        return None
    writable_folder(value, "--reports")
    return str(value)


def cmd_run(args) -> int:
    from exo_bench.bench.runner import run

    args.reports = reports_folder(args.reports)
    return run(args)


def _report_job(run, args, command: str) -> int:
    """A suite job run on its own: its files are marked with this process's run in the folder's
    runs.json and summary.md (bench/runner.py), so the summary always says which run made each file."""
    from exo_bench.bench.reporting import REPORTS
    from exo_bench.bench.runner import record_files, snapshot

    args.reports = reports_folder(args.reports)
    out = Path(args.reports) if args.reports else REPORTS
    before = snapshot(out)
    try:
        return run(args)
    finally:
        record_files(out, before, command + (" --full" if getattr(args, "full", False) else ""))


def _on_cluster(args) -> bool:
    """The full sweep runs on a Dask cluster (bench/distributed.py); so does the quick one when
    --workers or --scheduler is given."""
    return bool(getattr(args, "full", False) or args.workers is not None or args.scheduler
                or getattr(args, "rows", None))


def cmd_bench(args) -> int:
    from exo_bench.bench.bench_reports import run

    if _on_cluster(args):
        from exo_bench.bench.distributed import bench_run as run
    return _report_job(run, args, "exo-bench bench")


def cmd_errata(args) -> int:
    from exo_bench.bench.errata import run

    return _report_job(run, args, "exo-bench errata")


def cmd_stability(args) -> int:
    from exo_bench.bench.stability import run

    if _on_cluster(args):
        from exo_bench.bench.distributed import stability_evaluator
        args.evaluate = stability_evaluator(args)
    return _report_job(run, args, "exo-bench stability")


def _size_arg(text: str) -> int:
    from exo_bench.bench.resources import parse_size

    try:
        return parse_size(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--max-memory: ")) from None


def _seconds_arg(text: str) -> float:
    from exo_bench.bench.resources import parse_seconds

    try:
        return parse_seconds(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix("--max-time: ")) from None


def _budget_arg(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def _workers_arg(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of worker processes, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected at least 1 worker, got {value}")
    return value


def _limit_args(s) -> None:
    """``--budget``, ``--max-memory``, ``--max-time`` of ``inverse`` and ``forward``."""
    s.add_argument("--budget", type=_budget_arg, default=None, metavar="SECONDS",
                   help="seconds for lagrange's symbolic derivation (default 120; refused with any other method)")
    s.add_argument("--max-memory", type=_size_arg, default=None, metavar="SIZE", help=MAX_MEMORY_HELP)
    s.add_argument("--max-time", type=_seconds_arg, default=None, metavar="SECONDS",
                   help="refuse (one line, before any work) a method whose estimated time exceeds SECONDS "
                        "(default: no limit)")


def _cluster_args(s) -> None:
    s.add_argument("--workers", type=_workers_arg, default=None, metavar="N",
                   help="run the sweep on a local Dask cluster of N single-threaded worker processes (default: one "
                        "per core; 1 = serial)")
    s.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the sweep on the running Dask cluster at ADDRESS (e.g. tcp://10.0.0.1:8786)")


MAX_MEMORY_HELP = ("refuse (one line, before any work) a method whose estimated memory exceeds SIZE, e.g. 2G, 512M "
                   "(default: 80%% of the machine's available memory); the estimate and a method that fits are named")


def _version() -> str:
    import exo_bench

    return exo_bench.__version__


def _default_method() -> str:
    """The default method of ``exo-bench inverse``: the one ``prepare()`` takes when none is named."""
    import inspect

    from exo_bench.bench.methods import prepare

    return inspect.signature(prepare).parameters["method"].default


def build_parser() -> argparse.ArgumentParser:
    from exo_bench.bench.methods import method_names

    p = _Parser(prog="exo-bench", description="Equations of motion of variable-length rod exoskeletons: "
                "three implementations, cross-checked, timed and visualised.")
    p.add_argument("--version", action="version", version=f"exo-bench {_version()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    s = sub.add_parser("presets", help="list the preset mechanisms")
    s.set_defaults(func=cmd_presets)

    s = sub.add_parser("inverse", help="inverse dynamics: generalised forces for given states")
    s.add_argument("mechanism", help="a preset name or a mechanism JSON file")
    s.add_argument("states", help='a JSON file {"q": [[...]], "qd": [[...]], "qdd": [[...]]}, '
                   "one row per sample, coordinates in block order [phi..., psi..., l...]")
    default_method = _default_method()   # the same as the library's prepare()
    s.add_argument("--method", default=default_method,
                   help=f"one of: {', '.join(method_names())} (default: {default_method}, as prepare()'s; matrix-paper is eq. (18) as printed: WRONG in 3D by "
                        "design, kept to expose the paper's misprints; its results carry a warning on stderr)")
    _limit_args(s)
    s.set_defaults(func=cmd_inverse)

    s = sub.add_parser("forward", help="forward dynamics: accelerations for given states and forces")
    s.add_argument("mechanism", help="a preset name or a mechanism JSON file")
    s.add_argument("states", help='a JSON file {"q": [[...]], "qd": [[...]], "tau": [[...]]} (or .npz), '
                   "one row per sample, in block order [phi..., psi..., l...] and [M_phi..., M_psi..., F...]")
    s.add_argument("--method", default="newton-euler", help=f"one of: {', '.join(method_names())}")
    _limit_args(s)
    s.set_defaults(func=cmd_forward)

    s = sub.add_parser("urdf", help="print (or write) the generated URDF of a mechanism")
    s.add_argument("mechanism")
    s.add_argument("-o", "--output")
    s.set_defaults(func=cmd_urdf)

    s = sub.add_parser("mjcf", help="print (or write) the MJCF (MuJoCo XML) of a mechanism, checked by compiling it "
                                    "with MuJoCo (extra [peers])")
    s.add_argument("mechanism", help="a preset name or a mechanism JSON file")
    s.add_argument("-o", "--output", help="the .xml file to write (default: stdout)")
    s.add_argument("--no-check", action="store_true", help="write it without compiling it in MuJoCo (MuJoCo not needed)")
    s.set_defaults(func=cmd_mjcf)

    s = sub.add_parser("run", help="the main job: run every scene and write the reports")
    s.add_argument("scenes", nargs="*", help="shipped scene names or scene TOML files (default: every shipped scene)")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    s.add_argument("--full", action="store_true", help="the whole sweep in the benchmark and stability reports")
    s.add_argument("--max-memory", type=_size_arg, default=None, metavar="SIZE",
                   help="skip (with the reason in the reports) a scene's method whose estimated memory exceeds SIZE "
                        "(default: 80%% of the machine's available memory)")
    s.set_defaults(func=cmd_run)

    s = sub.add_parser("bench", help="run the benchmark suite and write paper_table, error_vs_runtime, scaling")
    s.add_argument("--full", action="store_true", help="the whole sweep (n up to 100, 10,000 samples); slow")
    s.add_argument("--update-readme", action="store_true",
                   help="also replace the paper table in the checkout's README.md (only then is README.md changed)")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    s.add_argument("--rows", action="append", default=None, metavar="PATTERN",
                   help="run only the sweep's rows whose key matches PATTERN (shell-style, repeatable; e.g. "
                        "'*test_forward_dynamics.py:3d-chain-*'); their reports go to REPORTS/selected-rows, never over "
                        "a whole sweep's, and their checkpoints are resumed by a later whole sweep")
    _cluster_args(s)
    s.set_defaults(func=cmd_bench)

    s = sub.add_parser("errata", help="check every printed formula of the paper against Lagrange and Pinocchio; "
                       "write errata.md")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    s.set_defaults(func=cmd_errata)

    s = sub.add_parser("stability", help="where each method breaks (extreme cases vs the 50-digit reference) and the "
                       "forward-dynamics round trip; write stability.md and its plots")
    s.add_argument("--full", action="store_true", help="the whole sweep (finer distances, n = 100, more tolerances)")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    _cluster_args(s)
    s.set_defaults(func=cmd_stability)

    from exo_bench.bench.equations import add_parser  # exo-bench equations (bench/equations.py)
    add_parser(sub)
    from exo_bench.bench.step.command import add_parser as add_gait  # exo-bench gait (bench/step/command.py)
    add_gait(sub)
    return p


def _terminate(signum, frame):
    raise KeyboardInterrupt  # so that staging folders are removed on SIGTERM as on Ctrl-C


#: The longest line an error prints: a user's value can be huge (a 400-digit integer, a long string).
MAX_LINE = 500


def _one_line(e: BaseException) -> str:
    text = str(e).strip()
    return _shorten(text.splitlines()[0] if text else type(e).__name__)


def _shorten(line: str) -> str:
    if len(line) <= MAX_LINE:
        return line
    cut = len(line) - MAX_LINE + 40
    return f"{line[:MAX_LINE // 2]} ... ({cut} characters left out) ... {line[-(MAX_LINE // 2 - 40):]}"


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """Python warnings as one line each on stderr (no source line, no file name)."""
    print(f"exo-bench: warning: {_one_line(message) if isinstance(message, BaseException) else str(message).splitlines()[0]}",
          file=sys.stderr)


def error_line(e: BaseException) -> str:
    """The one line (without the ``exo-bench: error:`` prefix) for an exception that ends a command:
    every budget or resource error names the budget and how to raise it."""
    from exo_bench.bench.resources import ResourceLimit

    if isinstance(e, ResourceLimit):
        return str(e)
    skip = getattr(e, "skip_reason", None)
    if skip:  # lagrange.BudgetExceeded: the derivation's time budget
        return f"{skip}; raise the budget with --budget SECONDS or choose another method (matrix-factored)"
    if isinstance(e, MemoryError):
        avail = _available()
        if str(e).strip():  # e.g. the Pinocchio backend's check of its Data against the available memory
            return f"out of memory: {_one_line(e)}"
        return (f"out of memory: the model or the batch did not fit in the {avail} available (the limit of every "
                "run; estimated beforehand, see --max-memory); try a smaller batch or method matrix-factored")
    if isinstance(e, RecursionError):  # sympy on a very large expression
        return (f"the symbolic derivation nested deeper than Python's recursion limit ({sys.getrecursionlimit()}): "
                "the model is too large for method lagrange; choose another method (matrix-factored)")
    if isinstance(e, RuntimeError) and any(k in str(e) for k in ("bad_alloc", "length_error", "Unable to allocate")):
        return (f"out of memory in Pinocchio ({_one_line(e)}): the model does not fit in the {_available()} available "
                "(see --max-memory); choose method matrix-factored")
    if isinstance(e, OSError):
        name = e.filename if e.filename is not None else ""
        return f"{name!s}: {e.strerror or _one_line(e)}" if name else (e.strerror or _one_line(e))
    return _one_line(e)


def _available() -> str:
    from exo_bench.models.prepared import available_memory

    a = available_memory()
    return "memory" if a is None else f"{a / 1e9:.1f} GB of memory"


def main(argv: list[str] | None = None) -> int:
    import signal
    import warnings

    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
    except ValueError:  # not the main thread (main() called from a thread): Ctrl-C handling only
        previous = None
    try:
        return _main(argv, warnings)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _main(argv, warnings) -> int:
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning   # one line each, not Python's file:line and source line
        try:
            args = build_parser().parse_args(argv)
            return int(args.func(args) or 0)
        except _UsageError as e:
            print(_shorten(str(e).splitlines()[0] if str(e).strip() else "exo-bench: usage error"), file=sys.stderr)
            return 2
        except KeyboardInterrupt:
            print("exo-bench: interrupted; the reports folder holds only whole files of earlier runs or of this one "
                  "(summary.md says which)", file=sys.stderr)
            return 130
        except BrokenPipeError:  # the reader of stdout went away (| head): nothing more to say
            _silence_stdout()
            return 0
        except (ValueError, OSError, MemoryError, RecursionError) as e:
            print(f"exo-bench: error: {_shorten(error_line(e))}", file=sys.stderr)
            return 2
        except Exception as e:  # noqa: BLE001 - never a traceback: budgets and anything unforeseen, one line
            if getattr(e, "skip_reason", None) or isinstance(e, RuntimeError) and "alloc" in str(e):
                print(f"exo-bench: error: {_shorten(error_line(e))}", file=sys.stderr)
            else:
                print(f"exo-bench: internal error: {type(e).__name__}: {_one_line(e)} (please report it)",
                      file=sys.stderr)
            return 2


def _silence_stdout() -> None:
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    sys.exit(main())
