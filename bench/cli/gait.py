"""``exo-bench gait``: the stored predicted step, and ``--solve`` to solve it again and compare.

* ``exo-bench gait [--dim 2|3]`` describes the stored step (settings, how it was solved, every constraint
  re-evaluated in numpy);
* ``exo-bench gait --solve [--dim 2|3]`` solves the problem again with the stored settings (CasADi and its
  IPOPT: the optional extra ``casadi``) and reports the solve time, iterations and constraint violation,
  and whether the new solution reproduces the stored one within :data:`exo_bench.bench.studies.step.data.REPRODUCE_TOL`
  (exit 0 when it does, 1 when it does not);
* ``--store`` (with ``--solve``) writes the new solution over the stored one (``bench/studies/step/data/``).
"""

from __future__ import annotations

import datetime as _dt

import numpy as np

from exo_bench.bench.studies.step import data


def add_parser(sub) -> None:
    """Register ``exo-bench gait`` on the CLI's subparsers."""
    from exo_bench.bench.cli.arguments import subcommand, whole

    s = subcommand(
        sub,
        "gait",
        cmd_gait,
        "the predicted walking step of exo5 (direct collocation): describe the stored step, or --solve it "
        "again and compare",
        "exo-bench gait --dim 3",
        "exo-bench gait --dim 2 --solve",
    )
    s.add_argument("--dim", type=whole, choices=(2, 3), default=3, help="exo5-2d or exo5-3d (default 3)")
    s.add_argument(
        "--solve",
        action="store_true",
        help="solve the step again (needs the extra 'casadi') and check it reproduces the stored one",
    )
    s.add_argument("--store", action="store_true", help="with --solve: write the new solution as the stored step")
    s.add_argument("--verbose", action="store_true", help="with --solve: IPOPT's iteration log")


def _mech(dim: int):
    from exo_bench.models.mechanism.presets import exo5

    return exo5(dim)


def describe(step: data.StoredStep, mech) -> list[str]:
    """Lines describing a stored step: what it is, how it was solved, its constraints in numpy."""
    s, meta = step.settings, step.meta
    sv = meta.get("solver", {})
    hip = data.hip_path(step, mech)
    viol = data.violations(step, mech)
    lines = [
        f"{mech.name}: one step of {step.duration:.4f} s, step length {step.step_length:.4f} m at the prescribed "
        f"{s.speed:g} m/s (Winter 1.41 m/s); {s.intervals} Hermite-Simpson intervals",
        f"  hip advances {hip[-1, 0] - hip[0, 0]:.4f} m (from {hip[0, 0]:+.4f} to {hip[-1, 0]:+.4f} m over O); "
        f"lowest swing-leg point mass in the clearance phase {data.lowest_swing_mass(step, mech)[int(round(s.window * 2 * s.intervals)) : int(round((1 - s.window) * 2 * s.intervals)) + 1].min() * 100:.3f} cm",
        f"  solved at {meta.get('commit', '?')} on {meta.get('date', '?')}: IPOPT {sv.get('status')}, "
        f"{sv.get('iterations')} iterations, {sv.get('solve_seconds', float('nan')):.1f} s, objective "
        f"{sv.get('objective', float('nan')):.6g}, constraint violation (CasADi) {sv.get('constraint_violation', float('nan')):.1e}",
        f"  constraints re-evaluated in numpy: largest violation {max(viol.values()):.1e} "
        f"({max(viol, key=lambda k: viol[k])})",
    ]
    return lines


def compare(stored: data.StoredStep, new) -> dict[str, float]:
    """Largest differences between a stored step and a new solution: duration, q, qd, qdd."""
    return {
        "duration": abs(stored.duration - new.duration),
        "q": float(np.abs(stored.q - new.q).max()),
        "qd": float(np.abs(stored.qd - new.qd).max()),
        "qdd": float(np.abs(stored.qdd - new.qdd).max()),
    }


def cmd_gait(args) -> int:
    mech = _mech(args.dim)
    if args.store and not args.solve:
        raise ValueError("gait: --store needs --solve (it writes the new solution)")
    if not args.solve:
        for line in describe(data.load(mech.name), mech):
            print(line)
        return 0
    from exo_bench.matrix_method.export.casadi_functions import require_casadi

    require_casadi()  # one line naming the extra when CasADi is missing
    from exo_bench.bench.studies.step.problem import solve

    try:
        stored = data.load(mech.name)
        settings = stored.settings
    except ValueError:
        if not args.store:
            raise
        from exo_bench.bench.studies.step.problem import StepSettings

        stored, settings = None, StepSettings(dim=args.dim)
    sol = solve(mech, settings, verbose=args.verbose)  # SolveFailed: one line, exit 2 (bench/cli/app.py)
    st = sol.stats
    print(
        f"{mech.name}: IPOPT {st['status']} in {st['iterations']} iterations, {st['solve_seconds']:.2f} s "
        f"(this host, now); constraint violation {st['constraint_violation']:.1e} (CasADi); objective {st['objective']:.8g}; "
        f"duration {sol.duration:.6f} s, step length {sol.step_length:.6f} m"
    )
    code = 0
    if stored is not None:
        diff = compare(stored, sol)
        same = diff["duration"] <= data.REPRODUCE_TOL and diff["q"] <= data.REPRODUCE_TOL
        print(
            f"against the stored step: |dT| {diff['duration']:.1e} s, max |dq| {diff['q']:.1e}, max |dqd| "
            f"{diff['qd']:.1e}, max |dqdd| {diff['qdd']:.1e}: "
            + (
                f"reproduces it (tolerance {data.REPRODUCE_TOL:g} s and rad/m on T and q)"
                if same
                else f"DIFFERS by more than the tolerance {data.REPRODUCE_TOL:g}"
            )
        )
        code = 0 if same else 1
    if args.store:
        from exo_bench.bench.output.provenance import _git_commit

        prov = {
            "commit": _git_commit(),
            "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC"),
            "command": f"exo-bench gait --solve --dim {args.dim} --store",
        }
        p = data.save(sol, mech, provenance=prov)
        print(f"wrote {p}")
        for line in describe(data.load(mech.name), mech)[-1:]:
            print(line)
    return code


__all__ = ["add_parser", "cmd_gait", "compare", "describe"]
