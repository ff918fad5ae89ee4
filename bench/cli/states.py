"""``exo-bench states MECHANISM -o FILE.json|FILE.npz [--samples N] [--seed S]``: example states.

Seeded random states (:func:`exo_bench.models.gait.motion.random_states`: elevations within 1.2 rad of
the horizontal, lengths from 0.3 m), checked away from singular and ill-conditioned mass matrices
(:meth:`exo_bench.models.runtime.prepared.PreparedModel.check_regular`, the check forward dynamics makes),
with ``tau``, the generalised forces of those states by the default method: a file that
``exo-bench inverse`` (q, qd, qdd) and ``exo-bench forward`` (q, qd, tau) both read as written.
The file goes through the one safe writer (bench/output/files.py: never through a link, never
half-written); ``-o -`` prints the JSON on stdout.
"""

from __future__ import annotations

import argparse

import numpy as np

from exo_bench.bench.cli.arguments import at_least_one, subcommand, whole

#: Example states are for reading and copying: a default that prints in a screen.
DEFAULT_SAMPLES = 10
#: Peak bytes per number written, predicted before the work: JSON holds each of the four arrays'
#: numbers as a float64 (8), a Python float in ``tolist`` (24 + an 8-byte list slot) and up to 25
#: characters of text twice (the pieces and the joined string); .npz the array and its archive copy.
JSON_BYTES_PER_NUMBER = 8 + 32 + 50
NPZ_BYTES_PER_NUMBER = 8 + 8


def add_parser(sub: argparse._SubParsersAction) -> None:
    s = subcommand(
        sub,
        "states",
        cmd_states,
        "write example states (q, qd, qdd and their tau) of a mechanism for inverse and forward",
        "exo-bench states exo5-3d -o states.json",
        "exo-bench states fig2a-2d -o states.npz --samples 100 --seed 3",
        mechanism=True,
    )
    s.add_argument(
        "-o", "--output", required=True, help="the file to write: .npz for NumPy arrays, else JSON (-: stdout)"
    )
    s.add_argument(
        "--samples", type=_count, default=DEFAULT_SAMPLES, help=f"rows of states (default {DEFAULT_SAMPLES})"
    )
    s.add_argument("--seed", type=_seed, default=0, help="the random seed (default 0): the same seed, the same file")


def _count(text: str) -> int:
    return at_least_one(text, "samples", "sample")


def check_memory(samples: int, dof: int, npz: bool) -> None:
    """Before any work: one ValueError line when the file's peak memory would exceed the usable memory."""
    from exo_bench.models.machine.memory import usable_memory

    need = 4 * samples * dof * (NPZ_BYTES_PER_NUMBER if npz else JSON_BYTES_PER_NUMBER)
    usable = usable_memory()
    if usable is not None and need > usable:
        most = max(1, usable // (4 * dof * (NPZ_BYTES_PER_NUMBER if npz else JSON_BYTES_PER_NUMBER)))
        raise ValueError(
            f"--samples: {samples} samples of {dof} coordinates need about {need / 1e9:.1f} GB, more than the "
            f"{usable / 1e9:.1f} GB usable; at most {most} fit"
        )


def _seed(text: str) -> int:
    value = whole(text)
    if not 0 <= value < 2**63:
        raise argparse.ArgumentTypeError(f"expected a seed from 0 to 2**63 - 1, got {value}")
    return value


def example_states(mechanism, samples: int, seed: int) -> dict[str, np.ndarray]:
    """``{"q", "qd", "qdd", "tau"}``, each ``(samples, dof)``; a singular or ill-conditioned sample is
    one ValueError line naming it (:meth:`~exo_bench.models.runtime.prepared.PreparedModel.check_regular`)."""
    from exo_bench.api import prepare
    from exo_bench.models.gait.motion import random_states

    q, qd, qdd = random_states(mechanism, samples, seed)
    model = prepare(mechanism)
    model.check_regular(q)
    tau = np.asarray(model.inverse_dynamics(q, qd, qdd), dtype=float)
    return {"q": q, "qd": qd, "qdd": qdd, "tau": tau}


def encoded(arrays: dict[str, np.ndarray], npz: bool) -> str | bytes:
    """The file's bytes: a ``.npz`` archive, or JSON with one row per sample."""
    if npz:
        import io

        buf = io.BytesIO()
        np.savez(buf, q=arrays["q"], qd=arrays["qd"], qdd=arrays["qdd"], tau=arrays["tau"])
        return buf.getvalue()
    import json

    return json.dumps({k: v.tolist() for k, v in arrays.items()}, allow_nan=False) + "\n"


def cmd_states(args: argparse.Namespace) -> int:
    from exo_bench.bench.output.files import checked_output, write_output
    from exo_bench.models.mechanism.presets import load_mechanism

    checked_output(args.output, "states -o", [args.mechanism])  # before any work
    mech = load_mechanism(args.mechanism)
    npz = str(args.output).endswith(".npz")
    check_memory(args.samples, mech.dof, npz)
    arrays = example_states(mech, args.samples, args.seed)
    write_output(args.output, encoded(arrays, npz), "states -o", [args.mechanism])
    return 0
