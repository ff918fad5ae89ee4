"""``exo-bench inverse MECHANISM STATES``: generalised forces for given states, as JSON on stdout."""

from __future__ import annotations

import argparse
import json
import sys
from typing import TYPE_CHECKING, TextIO

import numpy as np

from exo_bench.bench.cli.arguments import add_max_memory, budget_arg, seconds_arg

if TYPE_CHECKING:
    from exo_bench.api.cost_model import Limits


def add_parser(sub: argparse._SubParsersAction) -> None:
    from exo_bench.api import method_names

    from exo_bench.bench.cli.arguments import subcommand

    s = subcommand(
        sub,
        "inverse",
        cmd_inverse,
        "inverse dynamics: generalised forces for given states, printed as JSON on stdout",
        "exo-bench states exo5-3d -o states.json",
        "exo-bench inverse exo5-3d states.json",
        mechanism=True,
    )
    s.add_argument(
        "states",
        help='a JSON file {"q": [[...]], "qd": [[...]], "qdd": [[...]]}, '
        'one row per sample, coordinates in block order [phi..., psi..., l...]; optionally "f_ext": forces '
        "at the point masses, (samples, links, 3 points, dim) in newtons, world axes (docs/external-forces.md)",
    )
    default_method = _default_method()  # the same as the library's prepare()
    s.add_argument(
        "--method",
        default=default_method,
        help=f"one of: {', '.join(method_names())} (default: {default_method}, as prepare()'s; matrix-paper is eq. (18) as printed: WRONG in 3D by "
        "design, kept to expose the paper's misprints; its results carry a warning on stderr)",
    )
    add_limit_args(s)


def _default_method() -> str:
    """The default method of ``exo-bench inverse``: the one ``prepare()`` takes when none is named."""
    import inspect

    from exo_bench.api import prepare

    return inspect.signature(prepare).parameters["method"].default


def add_limit_args(s: argparse.ArgumentParser) -> None:
    """``--budget``, ``--max-memory``, ``--max-time`` of ``inverse`` and ``forward``."""
    s.add_argument(
        "--budget",
        type=budget_arg,
        default=None,
        metavar="SECONDS",
        help="seconds for lagrange's symbolic derivation (default 120; refused with any other method)",
    )
    add_max_memory(s)
    s.add_argument(
        "--max-time",
        type=seconds_arg,
        default=None,
        metavar="SECONDS",
        help="refuse (one line, before any work) a method whose estimated time exceeds SECONDS (default: no limit)",
    )


def refuse_budget(args: argparse.Namespace) -> None:
    """``--budget`` is lagrange's derivation budget: with another method it would be silently ignored."""
    from exo_bench.api.methods import budgeted_methods, derives_within_budget

    if args.budget is not None and not derives_within_budget(args.method):
        raise ValueError(
            f"--budget: the derivation budget of method {', '.join(budgeted_methods())}; method {args.method!r} "
            "derives nothing (limit its time with --max-time)"
        )


def budget_option(args: argparse.Namespace) -> dict:
    """The method's options from ``--budget``: its derivation budget where it derives (else none)."""
    from exo_bench.api.methods import derives_within_budget

    return {"budget": args.budget} if derives_within_budget(args.method) and args.budget is not None else {}


def _load_states(path: str, mech, third: str = "qdd") -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
    """The states of a JSON file ``{"q": [[...]], "qd": ..., "qdd": ...}`` or, for large batches, a
    NumPy ``.npz`` archive with arrays ``q``, ``qd``, ``qdd``; validated (names the file).
    ``third="tau"``: forward dynamics' states ``q``, ``qd``, ``tau``. Fourth: the optional external
    forces ``f_ext`` ``(samples, links, 3, dim)`` of the same file, checked (None without them;
    docs/external-forces.md)."""
    from exo_bench.models.runtime.external_forces import check_f_ext
    from exo_bench.models.mechanism.presets import read_json
    from exo_bench.models.states.states import as_states

    what = f"states {path!r}"
    if str(path).endswith(".npz"):
        data = _read_npz(path, what)
    else:
        data = read_json(path, what)
    if not isinstance(data, dict) or not {"q", "qd", third} <= data.keys():
        got = sorted(data) if isinstance(data, dict) else type(data).__name__
        raise ValueError(f"{what}: expected an object with keys ['q', 'qd', '{third}'], got {got}")
    try:
        q, qd, x = as_states(mech, data["q"], data["qd"], data[third], source=what)
    except ValueError as e:  # as_states calls its third array qdd
        raise ValueError(
            str(e).replace("field 'qdd'", f"field '{third}'").replace("qdd must", f"{third} must")
        ) from None
    f = data.get("f_ext")
    return q, qd, x, None if f is None else check_f_ext(mech, f, q.shape, True, what)


def _read_npz(path: str, what: str) -> dict:
    import zipfile

    from exo_bench.models.mechanism.presets import regular_file
    from exo_bench.models.machine.memory import usable_memory

    p = regular_file(path, what)  # the same checks and messages as every other file we read
    try:
        with zipfile.ZipFile(p) as zf:
            size = sum(i.file_size for i in zf.infolist())
    except (zipfile.BadZipFile, EOFError, OSError) as e:
        raise ValueError(f"{what}: expected a NumPy .npz archive, got a file that is not one ({e})") from None
    limit = usable_memory()
    if limit is not None and size > limit:
        raise ValueError(
            f"{what}: its arrays take {size / 1e9:.1f} GB, more than the {limit / 1e9:.1f} GB a run may "
            "use (--max-memory does not raise this); split the batch"
        )
    try:
        with np.load(p, allow_pickle=False) as z:
            return {k: (z[k] if k in ("q", "qd", "qdd", "tau", "f_ext") else None) for k in z.files}
    except (zipfile.BadZipFile, EOFError) as e:
        raise ValueError(f"{what}: expected a NumPy .npz archive, got a file that is not one ({e})") from None
    except ValueError as e:
        raise ValueError(f"{what}: cannot read the arrays: {str(e).splitlines()[0]}") from None
    except OSError as e:
        raise ValueError(f"{what}: cannot read: {e.strerror or e}") from None


def check_before_reading(path: str, mech, method: str, options: dict, limits: Limits, rows, third: str = "qdd"):
    """Refuse before the states file is read: a ``.npz`` with the whole run's estimate (its samples are
    in its headers; ``rows(samples)`` is what the method computes), a JSON file with the cost of
    reading it alone (its samples are known once parsed: the caller checks the run again then).
    Returns the file's :class:`~exo_bench.bench.cli.states_input.StatesFile`."""
    from exo_bench.api.cost_model import check, check_reading
    from exo_bench.bench.cli.states_input import peek_states

    peek = peek_states(path, mech.dof, third)
    if peek.samples is not None:
        check(mech, method, rows(peek.samples), options, limits, io=peek.io(mech.dof))  # before decompressing
    else:
        check_reading(path, peek.read_bytes, peek.read_seconds, limits)
    return peek


def _limits(args: argparse.Namespace, method: str) -> Limits:
    from exo_bench.api.cost_model import Limits
    from exo_bench.api.methods import derives_within_budget

    budget = args.budget if derives_within_budget(method) else None
    return Limits(memory=args.max_memory, seconds=args.max_time, budget=budget)


def _write_tau(method: str, tau: np.ndarray, out: TextIO, key: str = "tau") -> None:
    """``{"method": ..., "tau": [[...], ...]}`` (or ``key``) written row block by row block (no list of
    the whole batch is built); non-finite values are null (JSON has no NaN)."""
    out.write(json.dumps({"method": method})[:-1] + f', "{key}": [')
    for s0 in range(0, tau.shape[0], 4096):
        block = tau[s0 : s0 + 4096]
        rows = [[None if not np.isfinite(x) else float(x) for x in row] for row in block]
        text = json.dumps(rows, allow_nan=False)[1:-1]
        out.write((", " if s0 else "") + text)
    out.write("]}\n")


def cmd_inverse(args: argparse.Namespace) -> int:
    from exo_bench.api import method_class, prepare
    from exo_bench.api.methods import known_wrong_warning
    from exo_bench.api.cost_model import check
    from exo_bench.models.mechanism.presets import load_mechanism
    from exo_bench.models.states.states import force_names

    method_class(args.method)  # an unknown method fails before any file is read
    refuse_budget(args)
    mech = load_mechanism(args.mechanism)
    options = budget_option(args)
    limits = _limits(args, args.method)
    peek = check_before_reading(args.states, mech, args.method, options, limits, lambda samples: samples)
    q, qd, qdd, f_ext = _load_states(args.states, mech)
    check(mech, args.method, q.shape[0], options, limits, io=peek.io(mech.dof, q.shape[0]))  # before any work
    model = prepare(mech, args.method, **options)
    tau = np.asarray(model.inverse_dynamics(q, qd, qdd, check=False, f_ext=f_ext), dtype=float)  # validated above
    warn = known_wrong_warning(args.method, mech.dim)
    if warn:
        print(warn, file=sys.stderr)
    count, first = 0, (0, 0)
    for s0 in range(0, tau.shape[0], 65536):  # in row blocks: no (samples, dof) mask
        bad = ~np.isfinite(tau[s0 : s0 + 65536])
        if bad.any():
            if count == 0:  # the first NaN/Inf
                s, c = map(int, np.argwhere(bad)[0])
                first = (s0 + s, c)
            count += int(bad.sum())
    if count:  # JSON has no NaN: write null, and say so on stderr (never a silent NaN)
        print(
            f"exo-bench: warning: method {args.method!r} gave {count} NaN/Inf value(s), written as null "
            f"(first: sample {first[0]}, {force_names(mech)[first[1]]})",
            file=sys.stderr,
        )
    _write_tau(args.method, tau, sys.stdout)
    return 0
