"""``exo-bench mjcf MECHANISM [-o FILE] [--no-check]``: the MJCF (MuJoCo XML) of a mechanism, checked
by compiling it with MuJoCo (extra [peers])."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parser(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser(
        "mjcf",
        help="print (or write) the MJCF (MuJoCo XML) of a mechanism, checked by compiling it "
        "with MuJoCo (extra [peers])",
    )
    s.add_argument("mechanism", help="a preset name or a mechanism JSON file")
    s.add_argument("-o", "--output", help="the .xml file to write (default: stdout)")
    s.add_argument(
        "--no-check", action="store_true", help="write it without compiling it in MuJoCo (MuJoCo not needed)"
    )
    s.set_defaults(func=cmd_mjcf)


def cmd_mjcf(args: argparse.Namespace) -> int:
    """The MJCF of a mechanism, compiled by MuJoCo before it is written (so that a file written loads
    in MuJoCo); ``--no-check`` writes it without MuJoCo."""
    from exo_bench.models.loading import load_mechanism
    from exo_bench.models.mjcf import to_mjcf

    mech = load_mechanism(args.mechanism)
    if args.output:
        from exo_bench.bench.output.files import output_target
        from exo_bench.bench.output.provenance import writable_folder

        output_target(args.output, "mjcf -o")  # never a FIFO, a device, a socket (bench/output/files.py)
        writable_folder(Path(args.output).resolve().parent, "-o")
    if not args.no_check:
        from exo_bench.models.mjcf import check_nesting

        check_nesting(mech)  # a ValueError before any work, where MuJoCo's parser would refuse the depth
    text = to_mjcf(mech)
    if not args.no_check:
        from exo_bench.models.mujoco_backend import compile_mjcf

        compile_mjcf(text, f"MJCF of {mech.name!r}")  # ValueError: MuJoCo missing, or refusing the file
    if args.output:
        from exo_bench.bench.output.provenance import atomic_write

        atomic_write(args.output, text)
    else:
        sys.stdout.write(text)
    return 0
