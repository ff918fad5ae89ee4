"""``exo-bench mjcf MECHANISM [-o FILE] [--no-check] [--max-memory SIZE]``: the MJCF (MuJoCo XML) of a
mechanism, checked by compiling it with MuJoCo (extra [peers]). Before any work, a tree too deep for
MuJoCo's parser, or one whose compilation would need more memory than ``--max-memory`` (default: the
usable memory, :func:`exo_bench.models.machine.memory.usable_memory`), is refused in one line
(:func:`exo_bench.models.engines.mjcf.compile_bytes`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from exo_bench.bench.cli.arguments import add_max_memory, subcommand


def add_parser(sub: argparse._SubParsersAction) -> None:
    s = subcommand(
        sub,
        "mjcf",
        cmd_mjcf,
        "print (or write) the MJCF (MuJoCo XML) of a mechanism, checked by compiling it with MuJoCo (extra [peers])",
        "exo-bench mjcf exo5-3d -o exo5-3d.xml",
        "exo-bench mjcf exo5-2d --no-check",
        mechanism=True,
    )
    s.add_argument("-o", "--output", help="the .xml file to write (default, or -: stdout)")
    s.add_argument(
        "--no-check", action="store_true", help="write it without compiling it in MuJoCo (MuJoCo not needed)"
    )
    add_max_memory(
        s, "memory MuJoCo may use to compile the file, predicted before (default: 80%% of the available memory)"
    )


def cmd_mjcf(args: argparse.Namespace) -> int:
    """The MJCF of a mechanism, compiled by MuJoCo before it is written (so that a file written loads
    in MuJoCo); ``--no-check`` writes it without MuJoCo."""
    from exo_bench.models.mechanism.presets import load_mechanism
    from exo_bench.models.engines.mjcf import to_mjcf

    from exo_bench.bench.output.files import STDOUT, checked_output, stream_of, write_output

    out = STDOUT if args.output is None else args.output
    mech = load_mechanism(args.mechanism)
    checked_output(out, "mjcf -o", [args.mechanism])  # never a link, a FIFO, its input (bench/output/files.py)
    if stream_of(out) is None:
        from exo_bench.bench.output.provenance import writable_folder

        writable_folder(Path(out).resolve().parent, "-o")
    if not args.no_check:
        from exo_bench.models.engines.mjcf import check_nesting

        check_nesting(mech)  # a ValueError before any work, where MuJoCo's parser would refuse the depth
        check_memory(mech, args.max_memory)
    text = to_mjcf(mech)
    if not args.no_check:
        from exo_bench.models.engines.mujoco_backend import compile_mjcf

        compile_mjcf(text, f"MJCF of {mech.name!r}")  # ValueError: MuJoCo missing, or refusing the file
    write_output(out, text, "mjcf -o", [args.mechanism])
    return 0


def check_memory(mech, limit: int | None) -> None:
    """A ValueError, before any work, when compiling the MJCF of ``mech`` in MuJoCo would need more
    than ``limit`` bytes (None: the usable memory; unknown: no check)."""
    from exo_bench.models.machine.memory import usable_memory
    from exo_bench.models.engines.mjcf import compile_bytes, mujoco_sizes

    source = "--max-memory"
    if limit is None:
        limit, source = usable_memory(), "80% of the available memory; set the limit with --max-memory"
    need = compile_bytes(mech)
    if limit is not None and need > limit:
        nv, neq = mujoco_sizes(mech)
        raise ValueError(
            f"mjcf: compiling the MJCF of {mech.name!r} ({mech.nlinks} links, {nv} MuJoCo coordinates, {neq} ties) "
            f"needs about {_gib(need)} (MuJoCo's arena grows as nv^2), over the limit of {_gib(limit)} ({source}); "
            "write it without compiling with --no-check"
        )


def _gib(x: float) -> str:
    return f"{x / 2**30:,.1f} GiB" if x >= 2**30 else f"{x / 2**20:,.1f} MiB"
