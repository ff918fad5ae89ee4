"""``exo-bench``: the command line. Errors print one line on stderr and exit with code 2."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, no usage dump
        raise _UsageError(f"{self.prog}: {message}")


class _UsageError(Exception):
    pass


def _load_states(path: str, mech) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from exo_bench.models.mechanism import as_states

    from exo_bench.models.loading import read_json

    data = read_json(path, f"states {path!r}")
    if not isinstance(data, dict) or not {"q", "qd", "qdd"} <= data.keys():
        got = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise ValueError(f"states {path!r}: expected an object with keys ['q', 'qd', 'qdd'], got {got}")
    return as_states(mech, data["q"], data["qd"], data["qdd"], source=f"states {path!r}")


def cmd_presets(args) -> int:
    from exo_bench.models.presets import preset_descriptions

    for name, desc in preset_descriptions().items():
        print(f"{name:10s} {desc}")
    return 0


def cmd_inverse(args) -> int:
    from exo_bench.bench.methods import KNOWN_WRONG, method_class, prepare
    from exo_bench.models.loading import load_mechanism
    from exo_bench.models.mechanism import force_names

    method_class(args.method)  # an unknown method fails before any file is read
    mech = load_mechanism(args.mechanism)
    q, qd, qdd = _load_states(args.states, mech)
    options = {"budget": args.budget} if args.method == "lagrange" and args.budget is not None else {}
    model = prepare(mech, args.method, **options)
    tau = np.asarray(model.inverse_dynamics(q, qd, qdd, check=False), dtype=float)   # validated above
    if args.method in KNOWN_WRONG and mech.dim == 3:
        print(f"exo-bench: warning: method {args.method!r}: {KNOWN_WRONG[args.method]}", file=sys.stderr)
    bad = ~np.isfinite(tau)
    if bad.any():  # JSON has no NaN: write null, and say so on stderr (never a silent NaN)
        s, c = map(int, np.argwhere(bad)[0])
        print(f"exo-bench: warning: method {args.method!r} gave {int(bad.sum())} NaN/Inf value(s), written as null "
              f"(first: sample {s}, {force_names(mech)[c]})", file=sys.stderr)
    rows = [[None if not np.isfinite(x) else float(x) for x in row] for row in tau]
    json.dump({"method": args.method, "tau": rows}, sys.stdout, allow_nan=False)
    sys.stdout.write("\n")
    return 0


def cmd_urdf(args) -> int:
    from exo_bench.models.loading import load_mechanism
    from exo_bench.models.urdf import to_urdf

    text = to_urdf(load_mechanism(args.mechanism))
    if args.output:
        from exo_bench.bench.reporting import atomic_write
        atomic_write(args.output, text)
    else:
        sys.stdout.write(text)
    return 0


def cmd_run(args) -> int:
    from exo_bench.bench.runner import run

    return run(args)


def cmd_bench(args) -> int:
    from exo_bench.bench.bench_reports import run

    return run(args)


def cmd_errata(args) -> int:
    from exo_bench.bench.errata import run

    return run(args)


def cmd_stability(args) -> int:
    from exo_bench.bench.stability import run

    return run(args)


def build_parser() -> argparse.ArgumentParser:
    from exo_bench.bench.methods import method_names

    p = _Parser(prog="exo-bench", description="Equations of motion of variable-length rod exoskeletons: "
                "three implementations, cross-checked, timed and visualised.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    s = sub.add_parser("presets", help="list the preset mechanisms")
    s.set_defaults(func=cmd_presets)

    s = sub.add_parser("inverse", help="inverse dynamics: generalised forces for given states")
    s.add_argument("mechanism", help="a preset name or a mechanism JSON file")
    s.add_argument("states", help='a JSON file {"q": [[...]], "qd": [[...]], "qdd": [[...]]}, '
                   "one row per sample, coordinates in block order [phi..., psi..., l...]")
    s.add_argument("--method", default="pinocchio",
                   help=f"one of: {', '.join(method_names())} (matrix-paper is eq. (18) as printed: wrong in 3D by "
                        "design, kept to expose the paper's misprints)")
    s.add_argument("--budget", type=float, default=None,
                   help="seconds for lagrange's symbolic derivation (default 120)")
    s.set_defaults(func=cmd_inverse)

    s = sub.add_parser("urdf", help="print (or write) the generated URDF of a mechanism")
    s.add_argument("mechanism")
    s.add_argument("-o", "--output")
    s.set_defaults(func=cmd_urdf)

    s = sub.add_parser("run", help="the main job: run every scene and write the reports")
    s.add_argument("scenes", nargs="*", help="shipped scene names or scene TOML files (default: every shipped scene)")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    s.add_argument("--full", action="store_true", help="the whole sweep in the benchmark and stability reports")
    s.set_defaults(func=cmd_run)

    s = sub.add_parser("bench", help="run the benchmark suite and write paper_table, error_vs_runtime, scaling")
    s.add_argument("--full", action="store_true", help="the whole sweep (n up to 100, 10,000 samples); slow")
    s.add_argument("--update-readme", action="store_true",
                   help="also replace the paper table in the checkout's README.md (only then is README.md changed)")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    s.set_defaults(func=cmd_bench)

    s = sub.add_parser("errata", help="check every printed formula of the paper against Lagrange and Pinocchio; "
                       "write errata.md")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    s.set_defaults(func=cmd_errata)

    s = sub.add_parser("stability", help="where each method breaks (extreme cases vs the 50-digit reference) and the "
                       "forward-dynamics round trip; write stability.md and its plots")
    s.add_argument("--full", action="store_true", help="the whole sweep (finer distances, n = 100, more tolerances)")
    s.add_argument("--reports", default=None, help="output folder (default: ./reports in the current directory)")
    s.set_defaults(func=cmd_stability)
    return p


def _terminate(signum, frame):
    raise KeyboardInterrupt  # so that staging folders are removed on SIGTERM as on Ctrl-C


def main(argv: list[str] | None = None) -> int:
    import signal

    signal.signal(signal.SIGTERM, _terminate)
    try:
        args = build_parser().parse_args(argv)
        return int(args.func(args) or 0)
    except _UsageError as e:
        print(str(e), file=sys.stderr)
        return 2
    except (ValueError, OSError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        print(f"exo-bench: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("exo-bench: interrupted; nothing half-written was left in the reports folder", file=sys.stderr)
        return 130
    except MemoryError:
        print("exo-bench: error: out of memory: the model or the batch is too large for this machine; "
              "try a smaller batch or the matrix-factored method", file=sys.stderr)
        return 2
    except Exception as e:  # noqa: BLE001 - never a traceback: budgets and anything unforeseen, one line
        skip = getattr(e, "skip_reason", None)
        if skip:
            print(f"exo-bench: error: {skip}; raise the budget with --budget SECONDS or choose another method",
                  file=sys.stderr)
        else:
            msg = str(e).splitlines()[0] if str(e) else ""
            print(f"exo-bench: internal error: {type(e).__name__}: {msg} (please report it)", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
