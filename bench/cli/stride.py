"""``exo-bench stride``: the predicted stride of the 2D human with feet (issue 37).

* ``exo-bench stride [--variant human|exo] [--speed V]`` describes the stored stride (period, stride
  length, how it was solved, every constraint re-evaluated in numpy);
* ``--solve`` solves it again from the initial guess with the stored settings (or, with ``--store`` and
  none stored, the default ones) and says whether it reproduces the stored one within
  :data:`exo_bench.bench.studies.stride.reproduce.REPRODUCE_TOL` (exit 0 when it does, 1 when not);
* ``--store`` (with ``--solve``) writes the new solution as the stored stride.
"""

from __future__ import annotations

import datetime as _dt


def _speed(v: float) -> float:
    """``--speed``, read by the strict number parser (:func:`exo_bench.bench.cli.arguments.decimal`), in range."""
    from exo_bench.bench.studies.stride.data import speed_key

    speed_key(v)  # (0, 10) m/s, finite: one line otherwise
    return v


def add_parser(sub) -> None:
    """Register ``exo-bench stride`` on the CLI's subparsers."""
    from exo_bench.bench.cli.arguments import decimal, subcommand

    s = subcommand(
        sub,
        "stride",
        cmd_stride,
        "the predicted stride of the 2D human with feet (contact-implicit collocation): describe the "
        "stored stride, or --solve it again and compare",
        "exo-bench stride --variant human --speed 1.41",
        "exo-bench stride --solve --speed 1.41 --variant exo",
    )
    s.add_argument("--variant", choices=("human", "exo"), default="human", help="leg rods held (human) or free")
    s.add_argument("--speed", type=decimal, default=1.41, help="the prescribed average speed, m/s (default 1.41)")
    s.add_argument("--solve", action="store_true", help="solve again (needs the extra 'casadi') and compare")
    s.add_argument("--store", action="store_true", help="with --solve: write the new solution as the stored one")
    s.add_argument("--verbose", action="store_true", help="with --solve: IPOPT's iteration log")


def cmd_stride(args) -> int:
    from exo_bench.bench.studies.stride import data, reproduce
    from exo_bench.models.mechanism.presets import human

    speed = _speed(args.speed)
    mech = human(2)
    if args.store and not args.solve:
        raise ValueError("stride: --store needs --solve (it writes the new solution)")
    if not args.solve:
        for line in reproduce.describe(data.load(args.variant, speed, mech), mech):
            print(line)
        return 0
    from exo_bench.matrix_method.export.casadi_functions import require_casadi

    require_casadi()
    from exo_bench.bench.studies.stride import problem

    try:
        stored = data.load(args.variant, speed, mech)
        settings = problem.settings_from(stored.settings)
    except ValueError:
        if not args.store:
            raise
        stored, settings = None, problem.settings_for(mech, args.variant, speed)
    source = (stored.solver.get("start") if stored is not None else None) or {}
    if source:  # solved as a continuation from another stored stride: the same again
        src = data.load(source["variant"], source["speed"], mech)
        new = problem.solve_from(mech, settings, src, verbose=args.verbose)
    else:  # SolveFailed: one line, exit 2 (bench/cli/app.py)
        new = problem.solve_stages(mech, settings, verbose=args.verbose)
    sv = new.solver
    print(
        f"{mech.name} {args.variant} at {speed:g} m/s: IPOPT {sv['status']} in {sv['iterations']} iterations, "
        f"{sv['solve_seconds']:.1f} s (this host, now); constraint violation {sv['constraint_violation']:.1e}; "
        f"objective {sv['objective']:.8g}; period {new.period:.4f} s"
    )
    code = 0
    if stored is not None:
        d = reproduce.distance(stored, new)
        same = d <= reproduce.REPRODUCE_TOL
        verdict = "reproduces it" if same else "DIFFERS by more than"
        print(f"against the stored stride: max |dq| {d:.1e} rad/m: {verdict} (tolerance {reproduce.REPRODUCE_TOL:g})")
        code = 0 if same else 1
    if args.store:
        from exo_bench.bench.output.provenance import _git_commit

        new.meta["provenance"] = {
            "commit": _git_commit(),
            "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
            "command": f"exo-bench stride --solve --variant {args.variant} --speed {speed:g} --store",
        }
        print(f"wrote {data.save(new, mech)}")
    return code


__all__ = ["add_parser", "cmd_stride"]
