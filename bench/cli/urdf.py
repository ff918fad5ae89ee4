"""``exo-bench urdf MECHANISM [-o FILE]``: the generated URDF of a mechanism."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    from exo_bench.bench.cli.arguments import subcommand

    s = subcommand(
        sub,
        "urdf",
        cmd_urdf,
        "print (or write) the generated URDF of a mechanism",
        "exo-bench urdf exo5-3d -o exo5-3d.urdf",
        "exo-bench urdf fig2a-2d",
        mechanism=True,
    )
    s.add_argument("-o", "--output", help="the .urdf file to write (default, or -: stdout)")


def cmd_urdf(args: argparse.Namespace) -> int:
    from exo_bench.bench.output.files import STDOUT, checked_output, write_output
    from exo_bench.models.mechanism.presets import load_mechanism
    from exo_bench.models.engines.urdf import to_urdf

    out = STDOUT if args.output is None else args.output
    checked_output(out, "urdf -o", [args.mechanism])  # before any work (bench/output/files.py)
    write_output(out, to_urdf(load_mechanism(args.mechanism)), "urdf -o", [args.mechanism])
    return 0
