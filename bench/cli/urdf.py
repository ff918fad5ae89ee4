"""``exo-bench urdf MECHANISM [-o FILE]``: the generated URDF of a mechanism."""

from __future__ import annotations

import argparse
import sys


def add_parser(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("urdf", help="print (or write) the generated URDF of a mechanism")
    s.add_argument("mechanism")
    s.add_argument("-o", "--output")
    s.set_defaults(func=cmd_urdf)


def cmd_urdf(args: argparse.Namespace) -> int:
    from exo_bench.models.loading import load_mechanism
    from exo_bench.models.urdf import to_urdf

    if args.output:  # refused before any work when it names a FIFO, a device, a socket (bench/output/files.py)
        from exo_bench.bench.output.files import output_target

        output_target(args.output, "urdf -o")
    text = to_urdf(load_mechanism(args.mechanism))
    if args.output:
        from exo_bench.bench.output.provenance import atomic_write

        atomic_write(args.output, text)
    else:
        sys.stdout.write(text)
    return 0
