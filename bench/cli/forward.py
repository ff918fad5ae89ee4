"""``exo-bench forward MECHANISM STATES``: forward dynamics, the accelerations for given states and
forces, as JSON on stdout; a singular configuration is one line naming the sample, the link and the
reason (exit 2), never NaN."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from exo_bench.bench.cli.inverse import (
    _limits,
    _load_states,
    _write_tau,
    add_limit_args,
    budget_option,
    check_before_reading,
    refuse_budget,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    from exo_bench.api import method_names

    from exo_bench.bench.cli.arguments import subcommand

    s = subcommand(
        sub,
        "forward",
        cmd_forward,
        "forward dynamics: accelerations for given states and forces, printed as JSON on stdout",
        "exo-bench states exo5-3d -o states.json",
        "exo-bench forward exo5-3d states.json",
        mechanism=True,
    )
    s.add_argument(
        "states",
        help='a JSON file {"q": [[...]], "qd": [[...]], "tau": [[...]]} (or .npz), '
        "one row per sample, in block order [phi..., psi..., l...] and [M_phi..., M_psi..., F...]; optionally "
        '"f_ext": forces at the point masses, (samples, links, 3 points, dim) in newtons (docs/external-forces.md)',
    )
    s.add_argument("--method", default="newton-euler", help=f"one of: {', '.join(method_names())}")
    add_limit_args(s)


def cmd_forward(args: argparse.Namespace) -> int:
    """Forward dynamics: the accelerations ``qdd`` of states ``q, qd, tau``."""
    from exo_bench.api import method_class, prepare
    from exo_bench.api.cost_model import check
    from exo_bench.api.methods import known_wrong_warning, spec
    from exo_bench.models.runtime.conditioning import check_finite
    from exo_bench.models.mechanism.presets import load_mechanism

    method_class(args.method)  # an unknown method fails before any file is read
    refuse_budget(args)
    mech = load_mechanism(args.mechanism)
    options = budget_option(args)
    limits = _limits(args, args.method)

    def rows(samples: int) -> int:
        """Forward dynamics forms M: dof + 2 inverse-dynamics rows per sample for the methods without their own."""
        return samples * (1 if spec(args.method).own_forward_dynamics else mech.dof + 2)

    peek = check_before_reading(args.states, mech, args.method, options, limits, rows, third="tau")  # before reading
    q, qd, tau, f_ext = _load_states(args.states, mech, third="tau")
    check(mech, args.method, rows(q.shape[0]), options, limits, io=peek.io(mech.dof, q.shape[0]))  # before any work
    model = prepare(mech, args.method, **options)
    warn = known_wrong_warning(args.method, mech.dim)
    if warn:
        print(warn, file=sys.stderr)
    model.check_regular(q)  # singular or beyond the conditioning bound: named, before any work
    qdd = np.asarray(model.forward_dynamics(q, qd, tau, check=False, f_ext=f_ext), dtype=float)  # validated above
    check_finite(mech, qdd)  # forces too large for float64: one line naming the sample, never null
    _write_tau(args.method, qdd, sys.stdout, key="qdd")
    return 0
