"""``exo-bench urdf MECHANISM [-o FILE]``: the generated URDF of a mechanism."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    from exo_bench.bench.cli.arguments import described

    s = sub.add_parser(
        "urdf",
        **described(
            "print (or write) the generated URDF of a mechanism",
            "exo-bench urdf exo5-3d -o exo5-3d.urdf",
            "exo-bench urdf fig2a-2d",
        ),
    )
    s.add_argument("mechanism", help="a preset name (exo-bench presets) or a mechanism JSON file")
    s.add_argument("-o", "--output", help="the .urdf file to write (default, or -: stdout)")
    s.set_defaults(func=cmd_urdf)


def cmd_urdf(args: argparse.Namespace) -> int:
    from exo_bench.bench.output.files import STDOUT, checked_output, write_output
    from exo_bench.models.mechanism.loading import load_mechanism
    from exo_bench.models.engines.urdf import to_urdf

    out = STDOUT if args.output is None else args.output
    checked_output(out, "urdf -o", [args.mechanism])  # before any work (bench/output/files.py)
    write_output(out, to_urdf(load_mechanism(args.mechanism)), "urdf -o", [args.mechanism])
    return 0
