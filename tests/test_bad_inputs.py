"""The bad-input catalogue: every class of bad input, the one line a user sees, exit code 2.

:data:`CASES` is the single source of docs/errors.md: each case builds a command line (and its
files) in a fresh folder, runs ``exo_bench.bench.cli.main`` in-process, and asserts the exit code,
that stdout is empty, that stderr is one line with no traceback, and that the line contains the
case's key phrase. ``test_errors_md_is_current`` regenerates the catalogue from the same runs and
compares it with docs/errors.md, so the document cannot go stale; rewrite it with
``python tests/test_bad_inputs.py``.

The rows of issue 16's table are marked ``issue=...`` (docs/errors.md lists them with their tests).
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Callable

import numpy as np
import pytest

import issue34
from cli_runs import run_cli
from exo_bench.bench.cli import app as cli
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, exo5

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "errors.md"


# ------------------------------------------------------------------------------ files for the cases
def _states(m, samples=2, seed=0, path=None, **changes):
    q, qd, qdd = random_states(m, samples, seed)
    d = {"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}
    d.update(changes)
    path.write_text(json.dumps(d))
    return path


def _mech(d: Path, name="m.json", **changes):
    data = exo5(3).to_dict()
    for k, v in changes.items():
        if k.startswith("link") and k[4].isdigit():
            i, key = k[4:].split("_", 1)
            data["links"][int(i) - 1][key] = v
        else:
            data[k] = v
    (d / name).write_text(json.dumps(data))
    return d / name


def _s5(d: Path) -> Path:
    return _states(exo5(3), path=d / "s.json")


def _scene(d: Path, motion: str, mech="fig2a-2d", methods='["pinocchio"]') -> Path:
    (d / "sc.toml").write_text(f'mechanism = "{mech}"\nmethods = {methods}\n[motion]\n{motion}\n')
    return d / "sc.toml"


def _motion_file(d: Path, t, samples=3) -> Path:
    q, qd, qdd = random_states(chain(2, 2), samples, 1)
    (d / "mo.json").write_text(json.dumps({"t": t, "q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
    return _scene(d, 'kind = "states"\nfile = "mo.json"', mech="fig2a-2d")


def _chain_file(d: Path, n: int, dim: int) -> Path:
    (d / "c.json").write_text(chain(n, dim).to_json(indent=None))
    return d / "c.json"


def _on_chain(n: int, dim: int, samples: int, *options: str) -> Callable[[Path], list]:
    """The command line ``exo-bench inverse`` of an ``n``-link chain's file and ``samples`` states, then ``options``."""
    return lambda d: ["inverse", _chain_file(d, n, dim), _states(chain(n, dim), samples, path=d / "s.json"), *options]


def _npz(d: Path, **arrays) -> Path:
    np.savez(d / "s.npz", **arrays)
    return d / "s.npz"


def _raise(exc: BaseException):
    def method(self, q, qd, qdd, **options):
        raise exc

    return method


@dataclass
class Case:
    id: str
    kind: str  # the class of input, as docs/errors.md lists it
    argv: Callable[[Path], list]  # the command line, built in a fresh folder
    needle: str  # a phrase the line must contain
    rc: int = 2
    issue: str = ""  # the row of issue 16's table it covers
    patch: Callable[[pytest.MonkeyPatch], None] | None = None
    example: str = ""  # what the user typed, for the document
    tags: tuple = field(default_factory=tuple)
    progress: bool = False  # stdout holds run's progress bar (the error is on stderr)


def _no_preflight(mp):
    """Let the work start (the estimate would refuse first) to reach the error raised inside it."""
    mp.setattr("exo_bench.api.cost_model.check", lambda *a, **k: None)


def _budget_runs_out(mp):
    """Let lagrange's work start with nothing cached and its budget's clock advancing 1 s per reading:
    the budget runs out at the first check on any machine (issue 34, F1: no race with the wall clock)."""
    import itertools

    from exo_bench.lagrange import budget, derivation, numeric

    _no_preflight(mp)
    for module, name in ((derivation, "_SYMBOLIC"), (derivation, "_NUMERIC"), (numeric, "_CACHE")):
        mp.setattr(module, name, {})
    mp.setattr(budget._active, "clock", itertools.count(0.0, 1.0).__next__, raising=False)


def _method_raises(exc):
    def patch(mp):
        from exo_bench.matrix_method.prepared import MatrixFactored

        # the public call itself: whichever kernel route a call takes (lean, whole batch, chunks) raises
        mp.setattr(MatrixFactored, "inverse_dynamics", _raise(exc))

    return patch


def _pin_data_too_large(mp):
    _no_preflight(mp)
    mp.setattr("exo_bench.models.engines.pinocchio_backend.usable_memory", lambda: 50_000_000)


def _pin_bad_alloc(mp):
    from exo_bench.models.engines.pinocchio_backend import PinocchioRNEA

    mp.setattr(PinocchioRNEA, "_inverse_dynamics", _raise(RuntimeError("std::bad_alloc")))


MF = ["--method", "matrix-factored"]


def _output_folder(command: str) -> Case:
    """``command -o`` (urdf, mjcf: one file) naming a folder."""
    return Case(
        f"{command}-output-folder",
        f"{command} -o naming a folder",
        lambda d: [command, "fig1-2d", "-o", d],
        "<dir>: expected a file to write, got a folder",
    )


def _output_fifo(command: str, kind: str, *options: str) -> Case:
    """``command -o`` (urdf, mjcf: one file) naming a FIFO, which is never replaced."""
    return Case(
        f"{command}-output-fifo",
        kind,
        lambda d: [command, "fig1-2d", *options, "-o", _fifo(d)],
        f"{command} -o '<dir>/fifo': is a FIFO; only a regular file or nothing is ever replaced",
        issue="26: destroyed files",
    )


CASES = [
    # ---------------------------------------------------------------- the mechanism
    Case(
        "mechanism-missing",
        "mechanism: no such file or preset",
        lambda d: ["inverse", d / "none.json", _s5(d)],
        "not a preset",
    ),
    Case("mechanism-folder", "mechanism: a folder", lambda d: ["inverse", d, _s5(d)], "expected a file, got a folder"),
    Case(
        "mechanism-binary",
        "mechanism: a binary file",
        lambda d: ["inverse", _bin(d), _s5(d)],
        "mechanism '<dir>/bin.json': expected UTF-8 text",
        issue="binary file",
    ),
    Case(
        "mechanism-device",
        "mechanism: a device or FIFO",
        lambda d: ["inverse", "/dev/zero", _s5(d)],
        "expected a regular file",
    ),
    Case(
        "mechanism-nul",
        "mechanism: a path with a NUL character",
        lambda d: ["inverse", "m\0.json", _s5(d)],
        "and no such file",
    ),
    Case("mechanism-json", "mechanism: invalid JSON", lambda d: ["inverse", _text(d, "{oops"), _s5(d)], "invalid JSON"),
    Case(
        "mechanism-array",
        "mechanism: JSON that is not an object",
        lambda d: ["inverse", _text(d, "[1, 2]"), _s5(d)],
        "expected a JSON object",
    ),
    Case(
        "mechanism-missing-key",
        "mechanism: a missing key",
        lambda d: ["inverse", _text(d, '{"dim": 2, "g": 9.81}'), _s5(d)],
        "missing key(s) ['links']",
    ),
    Case(
        "mechanism-dim",
        "mechanism: dim not 2 or 3",
        lambda d: ["inverse", _mech(d, dim=4), _s5(d)],
        "field 'dim': expected 2 or 3, got 4",
    ),
    Case(
        "mechanism-negative-g",
        "mechanism: negative g",
        lambda d: ["inverse", _mech(d, g=-9.81), _s5(d)],
        "expected g >= 0: g is the magnitude of gravity",
        issue="negative g",
    ),
    Case(
        "mechanism-g-string",
        "mechanism: g not a number",
        lambda d: ["inverse", _mech(d, g="9.81"), _s5(d)],
        "field 'g': expected a finite number",
    ),
    Case(
        "mechanism-huge-masses",
        "mechanism: masses whose forces overflow float64",
        lambda d: ["inverse", _mech(d, link1_masses=[1e308, 1e308, 1e308]), _s5(d)],
        "the forces of masses this large overflow float64",
        issue="masses of 1e308",
    ),
    Case(
        "mechanism-negative-mass",
        "mechanism: a negative mass",
        lambda d: ["inverse", _mech(d, link2_masses=[1, -1, 1]), _s5(d)],
        "masses[1]': expected a finite mass >= 0",
    ),
    Case(
        "mechanism-fraction",
        "mechanism: n outside (0, 1)",
        lambda d: ["inverse", _mech(d, link3_n=1.5), _s5(d)],
        "field 'n': expected a fraction in (0, 1)",
    ),
    Case(
        "mechanism-parent-link1",
        "mechanism: a bad parent on link 1",
        lambda d: ["inverse", _mech(d, link1_parent=3), _s5(d)],
        "expected -1 (the support: the first link has no earlier link to hang from), got 3",
        issue="parent on link 1",
    ),
    Case(
        "mechanism-parent-later",
        "mechanism: a parent that is not an earlier link",
        lambda d: ["inverse", _mech(d, link3_parent=3), _s5(d)],
        "0..1 (links 1..2), got 3",
    ),
    Case(
        "mechanism-sign",
        "mechanism: sign not +1 or -1",
        lambda d: ["inverse", _mech(d, link2_sign=0), _s5(d)],
        "field 'sign': expected +1 or -1, got 0",
    ),
    Case(
        "mechanism-no-links",
        "mechanism: no links",
        lambda d: ["inverse", _mech(d, links=[]), _s5(d)],
        "expected a non-empty list of links",
    ),
    # ---------------------------------------------------------------- the states
    Case("states-missing", "states: no such file", lambda d: ["inverse", "exo5-3d", d / "none.json"], "no such file"),
    Case(
        "states-binary",
        "states: a binary file",
        lambda d: ["inverse", "exo5-3d", _bin(d)],
        "states '<dir>/bin.json': expected UTF-8 text",
        issue="binary file",
    ),
    Case("states-json", "states: invalid JSON", lambda d: ["inverse", "exo5-3d", _text(d, "{")], "invalid JSON"),
    Case(
        "states-keys",
        "states: missing keys",
        lambda d: ["inverse", "exo5-3d", _text(d, '{"q": []}')],
        "expected an object with keys ['q', 'qd', 'qdd']",
    ),
    Case(
        "states-ragged",
        "states: ragged rows",
        lambda d: ["inverse", "exo5-3d", _states(exo5(3), path=d / "s.json", q=[[0.5] * 15, [0.5] * 14])],
        "ragged rows",
        issue="ragged rows",
    ),
    Case(
        "states-shape",
        "states: the wrong number of coordinates",
        lambda d: ["inverse", "fig1-2d", _s5(d)],
        "expected shape (samples, 2) in the order phi1..l1, got (2, 15)",
    ),
    Case(
        "states-string",
        "states: an entry that is not a number",
        lambda d: ["inverse", "exo5-3d", _states(exo5(3), path=d / "s.json", qd=[["x"] * 15] * 2)],
        "expected real numbers, got 'x' (str) at sample 0, coordinate phi1",
    ),
    Case(
        "states-nan",
        "states: NaN",
        lambda d: ["inverse", "exo5-3d", _text(d, _nan_states())],
        "field 'qd' sample 1 coordinate phi1: expected a finite number, got nan",
    ),
    Case(
        "states-negative-length",
        "states: a negative rod length",
        lambda d: ["inverse", "fig1-2d", _text(d, '{"q": [0.1, -0.5], "qd": [0, 0], "qdd": [0, 0]}')],
        "expected a rod length >= 0, got -0.5",
    ),
    Case(
        "states-overflow",
        "states: lengths whose forces overflow float64",
        lambda d: ["inverse", "fig1-2d", _text(d, '{"q": [0.1, 1e200], "qd": [0, 0], "qdd": [0, 0]}')],
        "the forces would overflow float64",
    ),
    Case(
        "states-samples",
        "states: q, qd, qdd of different lengths",
        lambda d: ["inverse", "fig1-2d", _text(d, '{"q": [[0.1, 1]], "qd": [[0, 0], [0, 0]], "qdd": [[0, 0]]}')],
        "same number of samples",
    ),
    Case(
        "states-npz",
        "states: a .npz file that is not an archive",
        lambda d: ["inverse", "fig1-2d", _text(d, "not zip", "s.npz")],
        "expected a NumPy .npz archive",
    ),
    Case(
        "states-npz-object",
        "states: a .npz archive of Python objects",
        lambda d: [
            "inverse",
            "fig1-2d",
            _npz(d, q=np.array([[0.1, "a"]], dtype=object), qd=np.zeros((1, 2)), qdd=np.zeros((1, 2))),
        ],
        "field 'q': expected an array of real numbers, got dtype object",
    ),
    # ---------------------------------------------------------------- memory, time, budgets
    Case(
        "chain300-3d-default",
        "a 300-link 3D chain with method pinocchio (the default before issue 26)",
        _on_chain(300, 3, 1, "--max-memory", "2G", "--method", "pinocchio"),
        "method 'pinocchio' on 'chain300-3d' (n=300 links, dim=3, 1 sample(s)) needs about 23.7 GB",
        issue="300-link 3D chain",
        example="exo-bench inverse chain300-3d.json s.json --max-memory 2G --method pinocchio",
    ),
    Case(
        "chain300-2d-default",
        "a 300-link 2D chain with method pinocchio",
        _on_chain(300, 2, 1, "--max-memory", "2G", "--method", "pinocchio"),
        "matrix-factored fits",
        issue="300-link 3D chain",
    ),
    Case(
        "lagrange-50",
        "method lagrange on a 50-link chain",
        _on_chain(50, 2, 2, "--method", "lagrange", "--max-memory", "1000G"),
        "its derivation alone over the budget of 120 s (raise it with --budget SECONDS",
        issue="lagrange",
    ),
    Case(
        "lagrange-budget",
        "lagrange's derivation over its budget (--budget)",
        lambda d: [
            "inverse",
            "fig2a-3d",
            _states(chain(2, 3), 1, path=d / "s.json"),
            "--method",
            "lagrange",
            "--budget",
            "0.01",
        ],
        "exceeded the time budget of 0.01 s",
        issue="lagrange",
        patch=lambda mp: _budget_runs_out(mp),
    ),
    Case(
        "max-time",
        "a method over --max-time",
        _on_chain(300, 3, 1, "--method", "recurrence", "--max-time", "0.05", "--max-memory", "2G"),
        "over the time limit of 50 ms (--max-time)",
    ),
    Case(
        "batch-too-large",
        "a batch whose arrays alone exceed the limit",
        lambda d: [
            "inverse",
            "exo5-3d",
            _npz(d, **dict(zip(("q", "qd", "qdd"), random_states(exo5(3), 20000, 0)))),
            "--max-memory",
            "17M",
            *MF,
        ],
        "no method fits: the batch's arrays alone take",
    ),
    Case(
        "max-memory-value",
        "--max-memory not a size",
        lambda d: ["inverse", "exo5-3d", _s5(d), "--max-memory", "2X"],
        "expected a size such as 2G",
    ),
    Case(
        "budget-value",
        "--budget not a positive number",
        lambda d: ["inverse", "exo5-3d", _s5(d), "--budget", "-1"],
        "expected a positive number of seconds",
    ),
    Case(
        "memory-error",
        "out of memory inside a method",
        lambda d: ["inverse", "exo5-3d", _s5(d), *MF],
        "out of memory: the model or the batch did not fit",
        patch=_method_raises(MemoryError()),
    ),
    Case(
        "recursion-error",
        "sympy's recursion limit",
        lambda d: ["inverse", "exo5-3d", _s5(d), *MF],
        "nested deeper than Python's recursion limit",
        patch=_method_raises(RecursionError("maximum recursion")),
    ),
    Case(
        "pinocchio-data",
        "a Pinocchio Data larger than the memory a run may use",
        _on_chain(40, 3, 1, "--method", "pinocchio"),
        "(3D, 40 links, nv = 120) needs 65.3 MB, more than the 50.0 MB of memory it may use",
        patch=_pin_data_too_large,
    ),
    Case(
        "pinocchio-bad-alloc",
        "Pinocchio's own allocation failure",
        lambda d: ["inverse", "exo5-3d", _s5(d), "--method", "pinocchio"],
        "out of memory in Pinocchio (std::bad_alloc)",
        patch=_pin_bad_alloc,
    ),
    # ---------------------------------------------------------------- scenes and reports folders
    Case(
        "scene-unknown",
        "run: an unknown scene",
        lambda d: ["run", "no-such-scene", "--reports", d / "rep"],
        "not a shipped scene",
    ),
    Case(
        "scene-toml",
        "run: invalid TOML",
        lambda d: ["run", _text(d, "a = [", "x.toml"), "--reports", d / "rep"],
        "invalid TOML",
    ),
    Case(
        "scene-zero-samples",
        "run: a motion of 0 samples",
        lambda d: ["run", _scene(d, 'kind = "planar-gait"\nperiods = 0.0001'), "--reports", d / "rep"],
        "expected periods x samples_per_period >= 2 samples",
        issue="0 samples",
    ),
    Case(
        "scene-one-sample",
        "run: a states file of 1 sample",
        lambda d: ["run", _motion_file(d, [0.0], samples=1), "--reports", d / "rep"],
        "expected at least 2 samples",
        issue="0 samples",
    ),
    Case(
        "scene-times",
        "run: times not increasing",
        lambda d: ["run", _motion_file(d, [0.0, 0.2, 0.1]), "--reports", d / "rep"],
        "expected strictly increasing times, got t[1] = 0.2 then t[2] = 0.1",
        issue="t not increasing",
    ),
    Case(
        "reports-file",
        "--reports naming a file",
        lambda d: ["errata", "--reports", _text(d, "x", "afile")],
        "--reports '<dir>/afile': expected a folder, but it is a file",
        issue="--reports naming a file",
    ),
    Case(
        "reports-file-run",
        "--reports naming a file (run)",
        lambda d: ["run", "fig2a-2d", "--reports", _text(d, "x", "afile")],
        "expected a folder, but it is a file",
        issue="--reports naming a file",
    ),
    Case(
        "reports-under-file",
        "--reports under a file",
        lambda d: ["stability", "--reports", _text(d, "x", "afile") / "sub"],
        "lies under '<dir>/afile', which is a file",
    ),
    # ---------------------------------------------------------------- the distributed sweep (bench/cluster/cluster.py)
    Case(
        "workers-zero",
        "--workers 0",
        lambda d: ["bench", "--full", "--workers", "0", "--reports", d / "rep"],
        "argument --workers: expected at least 1 worker, got 0",
    ),
    Case(
        "workers-not-a-number",
        "--workers not a number",
        lambda d: ["stability", "--full", "--workers", "two", "--reports", d / "rep"],
        "expected a whole number of worker processes, got 'two'",
    ),
    Case(
        "scheduler-unreachable",
        "--scheduler where no scheduler answers",
        lambda d: ["bench", "--full", "--scheduler", "tcp://127.0.0.1:1", "--reports", d / "rep"],
        "--scheduler 'tcp://127.0.0.1:1': no Dask scheduler reachable there",
        patch=lambda mp: mp.setattr("exo_bench.bench.cluster.cluster.SCHEDULER_TIMEOUT", 1),
    ),
    Case(
        "scheduler-malformed",
        "--scheduler not an address",
        lambda d: ["stability", "--full", "--scheduler", "tcp://[bad", "--reports", d / "rep"],
        "no Dask scheduler reachable there",
    ),
    _output_folder("urdf"),
    Case(
        "urdf-output-under-file",
        "urdf -o under a file",
        lambda d: ["urdf", "fig1-2d", "-o", _text(d, "x", "f") / "u"],
        "<dir>/f/u: cannot make its folder '<dir>/f'",
    ),
    Case(
        "mjcf-unknown-mechanism",
        "mjcf: an unknown mechanism",
        lambda d: ["mjcf", "exo7-3d", "-o", d / "m.xml"],
        "mechanism 'exo7-3d': not a preset",
    ),
    _output_folder("mjcf"),
    Case(
        "mjcf-output-under-file",
        "mjcf -o under a file",
        lambda d: ["mjcf", "fig1-2d", "-o", _text(d, "x", "f") / "m.xml"],
        "-o '<dir>/f': expected a folder, but it is a file",
    ),
    Case(
        "mjcf-no-mujoco",
        "mjcf without MuJoCo installed (extra [peers])",
        lambda d: ["mjcf", "exo5-3d", "-o", d / "m.xml"],
        "pip install 'exo-bench[peers]'",
        patch=lambda mp: mp.setitem(sys.modules, "mujoco", None),
    ),
    Case(
        "method-no-drake",
        "a method whose engine is not installed (drake, extra [peers])",
        lambda d: ["inverse", "exo5-3d", _s5(d), "--method", "drake"],
        "drake: Drake is not installed",
        patch=lambda mp: [
            mp.setitem(sys.modules, m, None)
            for m in ("pydrake", "pydrake.multibody", "pydrake.multibody.plant", "pydrake.multibody.tree")
        ],
    ),
    Case("unknown-command", "an unknown command", lambda d: ["frobnicate"], "invalid choice"),
    Case("missing-argument", "a missing argument", lambda d: ["inverse", "exo5-3d"], "required"),
    Case(
        "unknown-method",
        "an unknown method",
        lambda d: ["inverse", "exo5-3d", _s5(d), "--method", "newton"],
        "method: expected one of",
    ),
    # ---------------------------------------------------------------- exo-bench equations
    Case(
        "equations-format",
        "equations: an unknown format",
        lambda d: ["equations", "fig2a-2d", "--format", "pdf", "-o", d],
        "expected one of latex, python, c, casadi",
    ),
    Case(
        "equations-no-format",
        "equations: no format",
        lambda d: ["equations", "fig2a-2d", "-o", d],
        "expected one of latex, python, c, casadi, got nothing",
    ),
    Case(
        "equations-mechanism",
        "equations: an unknown mechanism",
        lambda d: ["equations", "fig9-2d", "--format", "c", "-o", d],
        "not a preset",
    ),
    Case(
        "equations-output-file",
        "equations: -o naming a file",
        lambda d: ["equations", "fig2a-2d", "--format", "c", "-o", _text(d, "x", "afile")],
        "expected a folder, but it is a file",
    ),
    Case(
        "equations-output-under-file",
        "equations: an output folder that cannot be made (under a file)",
        lambda d: ["equations", "fig2a-2d", "--format", "latex", "-o", _text(d, "x", "afile") / "out"],
        "lies under '<dir>/afile', which is a file",
    ),
    Case(
        "equations-budget",
        "equations: a composition over its time budget (estimated before any work)",
        lambda d: ["equations", _chain_file(d, 200, 3), "--format", "c", "-o", d],
        "as c: composing and generating needs about 2.0 h (estimated before any work), over the budget of 120 s; "
        "raise it with --budget SECONDS",
    ),
    Case(
        "equations-budget-value",
        "equations: --budget not a positive number",
        lambda d: ["equations", "fig2a-2d", "--format", "c", "--budget", "0"],
        "expected a positive number of seconds",
    ),
    # ---------------------------------------------------------------- forward dynamics
    Case(
        "forward-vertical",
        "forward: a vertical rod (M singular)",
        lambda d: ["forward", "exo5-3d", _forward_states(d, psi=(2, math.pi / 2))],
        "sample 0: link 3 (swing_thigh): vertical rod",
    ),
    Case(
        "forward-zero-length",
        "forward: a rod of length zero (M singular)",
        lambda d: ["forward", "exo5-3d", _forward_states(d, l=(4, 0.0)), "--method", "pinocchio"],
        "link 5 (trunk): rod length l5 = 0",
    ),
    Case(
        "forward-qdd-given",
        "forward: states with qdd instead of tau",
        lambda d: ["forward", "exo5-3d", _s5(d)],
        "expected an object with keys ['q', 'qd', 'tau']",
    ),
    # ---------------------------------------------------------------- issue 26: files that are not regular files
    _output_fifo("urdf", "urdf -o naming a FIFO (never replaced)"),
    Case(
        "urdf-output-link-to-fifo",
        "urdf -o naming a symlink to a FIFO",
        lambda d: ["urdf", "fig1-2d", "-o", _link(d, _fifo(d))],
        "is a symlink to '<dir>/fifo', which is a FIFO",
        issue="26: destroyed files",
    ),
    Case(
        "urdf-output-dangling-link",
        "urdf -o naming a symlink to nothing",
        lambda d: ["urdf", "fig1-2d", "-o", _link(d, d / "nothing")],
        "which does not exist; refusing to write through a dangling",
        issue="26: destroyed files",
    ),
    _output_fifo("mjcf", "mjcf -o naming a FIFO", "--no-check"),
    Case(
        "equations-output-fifo",
        "equations: a FIFO where an output file goes",
        lambda d: ["equations", "fig2a-2d", "--format", "c", "-o", _fifo(d, "fig2a_2d.c").parent],
        "<dir>/fig2a_2d.c: is a FIFO; only a regular file or nothing is ever replaced",
        issue="26: destroyed files",
    ),
    Case(
        "reports-fifo",
        "--reports naming a FIFO",
        lambda d: ["errata", "--reports", _fifo(d)],
        "--reports '<dir>/fifo': expected a folder, but it is a device, FIFO or socket",
        issue="26: destroyed files",
    ),
    Case(
        "reports-dangling-link",
        "--reports naming a symlink to nothing",
        lambda d: ["run", "fig2a-2d", "--reports", _link(d, d / "gone")],
        "--reports '<dir>/link': expected a folder, but it is a symlink to '<dir>/gone', which does not exist",
        issue="26: smaller misses",
    ),
    # ---------------------------------------------------------------- issue 26: narrower runs, refused scenes
    Case(
        "scene-refused",
        "run: a scene refused for memory (earlier rows kept)",
        lambda d: ["run", _scene(d, 'kind = "planar-gait"'), "--reports", d / "rep", "--max-memory", "1M"],
        "scene 'sc' failed: scene 'sc': 1000 samples of 4 coordinates need about 17 MB of arrays, over the "
        "memory limit of 1 MB (--max-memory); use fewer samples (its earlier rows and files in '<dir>/rep' are kept)",
        progress=True,
        issue="26: narrower overwrites wider",
    ),
    # ---------------------------------------------------------------- issue 26: estimates before the work
    Case(
        "recurrence-1000-2d",
        "recurrence on a 1000-link 2D chain under --max-memory 1G",
        _on_chain(1000, 2, 1, "--method", "recurrence", "--max-memory", "1G"),
        "method 'recurrence' on 'chain1000-2d' (n=1000 links, dim=2, 1 sample(s)) needs about 3.5 GB",
        issue="26: estimates",
    ),
    Case(
        "npz-bomb",
        "states: a small compressed .npz whose arrays inflate beyond the limit (judged from its headers)",
        lambda d: ["inverse", "exo5-3d", _npz_zeros(d, 2_000_000, 15), "--max-memory", "1G"],
        "(n=5 links, dim=3, 2000000 sample(s)) needs about",
        issue="26: estimates",
    ),
    Case(
        "max-time-reading",
        "--max-time counts reading the states",
        lambda d: ["inverse", "exo5-3d", _states(exo5(3), 40000, path=d / "s.json"), "--max-time", "0.5"],
        "reading it needs about",
        issue="26: estimates",
    ),
    Case(
        "max-time-writing",
        "--max-time counts writing tau",
        lambda d: [
            "inverse",
            "exo5-3d",
            _npz(d, **dict(zip(("q", "qd", "qdd"), random_states(exo5(3), 100000, 0)))),
            "--max-time",
            "1",
        ],
        "(reading the states and writing tau:",
        issue="26: estimates",
    ),
    # ---------------------------------------------------------------- issue 26: smaller misses
    Case(
        "states-json-true",
        "states: JSON true where a number goes",
        lambda d: ["inverse", "fig1-2d", _text(d, '{"q": [[0.1, true]], "qd": [[0, 0]], "qdd": [[0, 0]]}')],
        "field 'q': expected numbers, got True (a boolean) at sample 0, column 1",
        issue="26: smaller misses",
    ),
    Case(
        "states-duplicate-key",
        "states: a key given twice",
        lambda d: [
            "inverse",
            "fig1-2d",
            _text(d, '{"q": [[0.1, 1]], "qd": [[0, 0]], "qdd": [[0, 0]], "q": [[0.2, 1]]}'),
        ],
        "invalid JSON: duplicate key 'q' in one object",
        issue="26: smaller misses",
    ),
    Case(
        "mechanism-duplicate-key",
        "mechanism: a key given twice",
        lambda d: ["inverse", _text(d, exo5(3).to_json(indent=None)[:-1] + ', "g": 1.0}', "m.json"), _s5(d)],
        "invalid JSON: duplicate key 'g' in one object",
        issue="26: smaller misses",
    ),
    Case(
        "mechanism-name-nul",
        "mechanism: a NUL character in a link name",
        lambda d: ["urdf", _mech(d, link2_name="thigh\0"), "-o", d / "u.urdf"],
        "link 2: field 'name': expected printable characters only, got a control character U+0000 at position 5",
        issue="26: smaller misses",
    ),
    Case(
        "scene-gait-period",
        "run: a gait period T = 1e-300 s",
        lambda d: ["run", _scene(d, 'kind = "planar-gait"\n[motion.gait]\nT = 1e-300'), "--reports", d / "rep"],
        "field 'motion.gait.T': expected a gait whose",
        issue="26: smaller misses",
    ),
    Case(
        "scene-name-slash",
        "run: a scene named a/b",
        lambda d: [
            "run",
            _text(
                d,
                'name = "a/b"\nmechanism = "fig2a-2d"\nmethods = ["pinocchio"]\n[motion]\nkind = "planar-gait"\n',
                "sc.toml",
            ),
            "--reports",
            d / "rep",
        ],
        "field 'name': expected a name usable as a file name",
        issue="26: smaller misses",
    ),
    Case(
        "budget-other-method",
        "--budget with a method other than lagrange",
        lambda d: ["inverse", "exo5-3d", _s5(d), "--budget", "10", "--method", "recurrence"],
        "--budget: the derivation budget of method lagrange; method 'recurrence' derives nothing",
        issue="26: smaller misses",
    ),
    # ---------------------------------------------------------------- warnings and accepted edges (exit 0)
    Case(
        "mechanism-name-dashes",
        "mechanism: '--' in a link name (a JSON string in the URDF's comment, '--' as '\\u002d-')",
        lambda d: ["inverse", _mech(d, link2_name="thigh--left-"), _s5(d), "--method", "pinocchio"],
        "",
        rc=0,
        issue="26: smaller misses",
    ),
    Case(
        "matrix-paper-3d",
        "matrix-paper on a 3D model (a result with a warning)",
        lambda d: ["inverse", "exo5-3d", _s5(d), "--method", "matrix-paper"],
        "3D results are wrong by design",
        rc=0,
        issue="matrix-paper",
    ),
    Case(
        "matrix-paper-2d",
        "matrix-paper on a 2D model (a result with a warning)",
        lambda d: ["inverse", "fig2a-2d", _states(chain(2, 2), path=d / "s.json"), "--method", "matrix-paper"],
        "wrong in 3D by design",
        rc=0,
        issue="matrix-paper",
    ),
    Case(
        "nan-result",
        "a method that returns NaN (written as null, with a warning)",
        lambda d: [
            "inverse",
            "exo5-3d",
            _states(exo5(3), path=d / "s.json", q=[[0.0] * 5 + [1.2] * 5 + [0.5] * 5] * 2),
            "--method",
            "matrix-paper",
        ],
        "NaN/Inf value(s), written as null",
        rc=0,
    ),
    Case(
        "negative-zero-g",
        "g = -0.0 (accepted: it is 0)",
        lambda d: ["inverse", _mech(d, g=-0.0), _s5(d), *MF],
        "",
        rc=0,
    ),
]


def _fifo(d: Path, name: str = "fifo") -> Path:
    """A FIFO in the test's own folder (never a system device)."""
    os.mkfifo(d / name)
    return d / name


def _link(d: Path, target: Path, name: str = "link") -> Path:
    os.symlink(target, d / name)
    return d / name


def _npz_zeros(d: Path, samples: int, dof: int) -> Path:
    """A compressed .npz of zeros: a few MB on disk, ``3 x samples x dof x 8`` bytes inflated."""
    z = np.zeros((samples, dof))
    np.savez_compressed(d / "z.npz", q=z, qd=z, qdd=z)
    return d / "z.npz"


def _bin(d: Path) -> Path:
    (d / "bin.json").write_bytes(bytes(range(256)))
    return d / "bin.json"


def _forward_states(d: Path, psi=None, l=None) -> Path:
    """``{"q", "qd", "tau"}`` of exo5-3d with rod ``psi[0]`` at elevation ``psi[1]`` or rod ``l[0]`` of
    length ``l[1]`` (0-based rods) in sample 0."""
    q, qd, qdd = random_states(exo5(3), 2, 0)
    if psi is not None:
        q[0, 5 + psi[0]] = psi[1]
    if l is not None:
        q[0, 10 + l[0]] = l[1]
    (d / "f.json").write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "tau": qdd.tolist()}))
    return d / "f.json"


def _text(d: Path, text: str, name: str = "t.json") -> Path:
    (d / name).write_text(text)
    return d / name


def _nan_states() -> str:
    q, qd, qdd = random_states(exo5(3), 2, 0)
    qd[1, 0] = np.nan
    return json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()})  # JSON's NaN extension


def run_case(case: Case, folder: Path) -> tuple[int, str, str, list]:
    folder.mkdir(parents=True, exist_ok=True)
    cwd = os.getcwd()
    with pytest.MonkeyPatch.context() as mp:
        if case.patch:
            case.patch(mp)
        os.chdir(folder)
        try:
            argv = [str(a) for a in case.argv(folder)]
            rc, out, err = run_cli(argv)
        finally:
            os.chdir(cwd)
    return rc, out, err, argv


@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_bad_input(case, tmp_path):
    rc, out, err, _ = run_case(case, tmp_path)
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert rc == case.rc, err
    if case.rc == 2:
        assert (out == "" or case.progress) and len(lines) == 1, err
        assert lines[0].startswith("exo-bench"), lines[0]
    else:
        assert all(line.startswith("exo-bench: warning: ") for line in lines), err
        json.loads(out)
    text = err.replace(str(tmp_path), "<dir>")
    assert case.needle in text, (case.needle, text)


def test_the_method_help_says_matrix_paper_is_wrong_in_3d_by_design():
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
        cli.main(["inverse", "--help"])
    text = " ".join(buf.getvalue().split())
    assert "matrix-paper is eq. (18) as printed: WRONG in 3D by design" in text and "warning on stderr" in text


def test_the_300_link_chain_is_refused_with_the_default_limit_before_any_work(tmp_path, monkeypatch):
    """Method pinocchio (the CLI's default before issue 26) and no --max-memory, on a machine where 16 GB
    may be used: one line naming a method that fits, and Pinocchio never builds a model or a Data (the
    refusal is the estimate alone)."""
    import exo_bench.models.engines.pinocchio_backend as pb

    monkeypatch.setattr("exo_bench.api.cost_model.usable_memory", lambda: 16 * 10**9)
    monkeypatch.setattr(pb, "build_model", lambda mech: pytest.fail("a model was built"))
    monkeypatch.setattr(pb.PinocchioRNEA, "__init__", lambda *a, **k: pytest.fail("the method was prepared"))
    f = _chain_file(tmp_path, 300, 3)
    rc, out, err = run_cli(["inverse", f, _states(chain(300, 3), 1, path=tmp_path / "s.json"), "--method", "pinocchio"])
    assert rc == 2 and out == "" and len(err.strip().splitlines()) == 1
    assert "over the memory limit of 16.0 GB (80% of the available memory" in err and "matrix-factored fits" in err


def test_the_300_link_chain_answers_within_2_gb_with_a_method_that_fits(tmp_path):
    """The method the refusal names does answer, under --max-memory 2G (and agrees with recurrence,
    an independent route, on a sample)."""
    m = chain(300, 3)
    q, qd, qdd = random_states(m, 1, 3)
    (tmp_path / "s.json").write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
    rc, out, err = run_cli(["inverse", _chain_file(tmp_path, 300, 3), tmp_path / "s.json", "--max-memory", "2G", *MF])
    assert rc == 0 and err == ""
    tau = np.array(json.loads(out)["tau"])
    from exo_bench.api import prepare

    ref = prepare(m, "recurrence").inverse_dynamics(q, qd, qdd)
    assert np.abs(tau - ref).max() <= 16 * np.finfo(float).eps * m.dof * np.abs(ref).max()


# ------------------------------------------------------------------------------ issue 26
def _is_fifo(p: Path) -> bool:
    import stat

    return stat.S_ISFIFO(os.lstat(p).st_mode)


def test_nothing_replaces_a_fifo_for_any_command_that_writes(tmp_path, monkeypatch):
    """urdf -o, equations -o, equations --size-report, run --reports: a FIFO in a temporary folder
    where a file would go is refused in one line (exit 2) and is still a FIFO afterwards."""
    import exo_bench.bench.studies.equations_size as eq

    monkeypatch.setattr(
        eq, "size_point", lambda mech, route, budget: {"compose": 0.1, "generate": 0.1, "ops": 10, "c_lines": 5}
    )
    runs, cmd_o = [], {"u.urdf": "urdf -o ", "m.xml": "mjcf -o "}
    for name, argv in [
        ("u.urdf", lambda f: ["urdf", "fig1-2d", "-o", f]),
        ("m.xml", lambda f: ["mjcf", "fig1-2d", "--no-check", "-o", f]),
        ("fig2a_2d.c", lambda f: ["equations", "fig2a-2d", "--format", "c", "-o", f.parent]),
        ("equations_size.md", lambda f: ["equations", "--size-report", "--reports", f.parent]),
        (
            "summary.md",
            lambda f: ["run", _scene(f.parent, 'kind = "planar-gait"\nsamples_per_period = 40'), "--reports", f.parent],
        ),
    ]:
        d = tmp_path / name.replace(".", "_")
        d.mkdir()
        fifo = _fifo(d, name)
        rc, out, err = run_cli(argv(fifo))
        runs.append((name, rc, err))
        assert rc == 2 and "Traceback" not in err, (name, err)
        assert [ln for ln in err.splitlines() if "error" in ln] == [
            f"exo-bench: error: {cmd_o[name] + repr(str(fifo)) if name in cmd_o else fifo}: is a FIFO; only a regular "
            "file or nothing is ever replaced"
        ], (name, err)
        assert _is_fifo(fifo), name
        assert not list(d.glob(".staging-*")) and not list(d.glob(f".{name}.*")), name  # nothing half-written


@pytest.mark.case("S4")
def test_a_symlink_to_a_regular_file_is_refused_and_the_file_kept(tmp_path):
    """A symlink to a regular file named by ``-o`` is refused in one line naming the link (issue 26
    wrote through it; issue 34 S4: a write never follows a link); the file it points to is kept."""
    target = _text(tmp_path, "old", "real.urdf")
    link = _link(tmp_path, target)
    rc, out, err = run_cli(["urdf", "fig1-2d", "-o", link])
    assert rc == 2 and f"urdf -o {str(link)!r}: is a symlink to {str(target)!r}" in err, err
    assert link.is_symlink() and target.read_text() == "old"


def test_a_refused_scene_keeps_the_earlier_rows_and_files_byte_for_byte(tmp_path):
    sc = _scene(tmp_path, 'kind = "planar-gait"\nsamples_per_period = 40')
    rep = tmp_path / "rep"
    assert run_cli(["run", sc, "--reports", rep])[0] == 0
    before = {p.name: p.read_bytes() for p in rep.iterdir()}
    assert "| sc | pinocchio |" in before["summary.md"].decode()
    rc, out, err = run_cli(["run", sc, "--reports", rep, "--max-memory", "1K"])
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "scene 'sc' failed" in err, err
    assert {p.name: p.read_bytes() for p in rep.iterdir()} == before


def test_a_scene_failing_midway_keeps_its_rows_while_the_others_are_updated(tmp_path, monkeypatch):

    from exo_bench.bench.cli import run as runner
    from exo_bench.bench.studies.options import RunOptions

    a = _scene(tmp_path, 'kind = "planar-gait"\nsamples_per_period = 40')
    b = tmp_path / "b.toml"
    b.write_text(a.read_text())
    rep = tmp_path / "rep"
    assert runner.run_main_job(RunOptions(scenes=(str(a), str(b)), reports=rep)) == 0
    old_b = (rep / "b.md").read_bytes()
    real = runner.run_scene

    def half_then_fail(scene, staging, limits=None):
        if scene.name == "b":
            (staging / "b.md").write_text("half")
            raise RuntimeError("solver exploded")
        return real(scene, staging, limits)

    monkeypatch.setattr(runner, "run_scene", half_then_fail)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = runner.run_main_job(RunOptions(scenes=(str(a), str(b)), reports=rep))
    assert rc == 2 and "scene 'b' failed: RuntimeError: solver exploded" in err.getvalue()
    assert (rep / "b.md").read_bytes() == old_b
    summary = (rep / "summary.md").read_text()
    assert "(scene failed)" not in summary and "| b | pinocchio |" in summary


def test_stale_staging_folders_are_removed_by_the_next_run_and_live_ones_reported(tmp_path):
    import socket
    import subprocess

    rep = tmp_path / "rep"
    rep.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (rep / ".staging-killed").mkdir()
    (rep / ".staging-killed" / "x.md").write_text("half")
    (rep / ".staging-killed" / ".owner").write_text(f"{dead.stdout.strip()} 1 {socket.gethostname()}\n")
    (rep / ".staging-elsewhere").mkdir()
    (rep / ".staging-elsewhere" / ".owner").write_text("1 1 another-host\n")
    rc, out, err = run_cli(["run", _scene(tmp_path, 'kind = "planar-gait"\nsamples_per_period = 40'), "--reports", rep])
    assert rc == 0, err
    assert not (rep / ".staging-killed").exists() and (rep / ".staging-elsewhere").exists()
    assert "removed 1 staging folder(s)" in err and "left 1 staging folder(s)" in err and ".staging-elsewhere" in err


def test_a_quick_size_report_never_replaces_a_full_one(tmp_path, monkeypatch):
    import exo_bench.bench.studies.equations_size as eq

    monkeypatch.setattr(
        eq, "size_point", lambda mech, route, budget: {"compose": 0.1, "generate": 0.1, "ops": 10, "c_lines": 5}
    )
    rep = tmp_path / "rep"
    rep.mkdir()
    full = "# sizes\n\n_Generated by `exo-bench equations --size-report --full`; do not edit by hand._\n"
    (rep / "equations_size.md").write_text(full)
    rc, out, err = run_cli(["equations", "--size-report", "--reports", rep])
    assert rc == 0, err
    assert (rep / "equations_size.md").read_text() == full
    quick = (rep / "equations_size-quick.md").read_text()
    assert "equations_size-quick.png" in quick and (rep / "equations_size-quick.png").exists()


@pytest.mark.parametrize("how", ["runs.json", "provenance"])
def test_stability_reports_of_a_full_run_get_quick_names_beside_them(tmp_path, how):
    from exo_bench.bench.output.files import narrower_names

    names = ["stability-families.png", "stability.md"]
    if how == "runs.json":
        (tmp_path / "runs.json").write_text(
            json.dumps(
                {
                    "format": 1,
                    "runs": {"r1": {"command": "exo-bench stability --full"}},
                    "files": {"stability.md": {"run": "r1"}},
                }
            )
        )
    else:
        (tmp_path / "stability.md").write_text("# x\n\n_Generated by `exo-bench run --full`; do not edit by hand._\n")
    assert narrower_names(tmp_path, names, full=False) == {n: n.replace(".", "-quick.") for n in names}
    assert narrower_names(tmp_path, names, full=True) == {n: n for n in names}
    assert narrower_names(tmp_path / "empty", names, full=False) == {n: n for n in names}


def test_a_stability_run_without_casadi_never_replaces_a_report_with_the_analytic_runs(tmp_path):
    """The main job on a machine without the extra ``casadi`` cannot run the analytic Jacobian: its
    stability report goes beside one that has those runs, full run or not; with casadi, or over a
    report without them, it replaces the report as before."""
    from pathlib import Path

    from exo_bench.bench.output.files import has_line, narrower_names
    from exo_bench.bench.studies.stability.forward_report import TABLE_HEAD

    names = ["stability-families.png", "stability.md"]
    same, quick = {n: n for n in names}, {n: n.replace(".", "-quick.") for n in names}
    head = "# x\n\n_Generated by `exo-bench stability`; do not edit by hand._\n\n"
    (tmp_path / "stability.md").write_text(head + TABLE_HEAD + " of them in FD Jacobians |\n|---|\n")
    assert narrower_names(tmp_path, names, full=False, lacks=TABLE_HEAD) == quick
    assert narrower_names(tmp_path, names, full=True, lacks=TABLE_HEAD) == quick
    assert narrower_names(tmp_path, names, full=False) == same
    (tmp_path / "stability.md").write_text(head + "No analytic runs in this report.\n")
    assert narrower_names(tmp_path, names, full=False, lacks=TABLE_HEAD) == same
    # the marker is the committed report's own table header (written with casadi: a wider run's, in reports/full)
    assert has_line(Path(__file__).resolve().parent.parent / "reports" / "full", ["stability.md"], TABLE_HEAD)


def test_a_compressed_npz_is_judged_before_it_is_inflated(tmp_path, monkeypatch):
    f = _npz_zeros(tmp_path, 2_000_000, 15)
    assert f.stat().st_size < 10e6  # 720 MB of arrays
    monkeypatch.setattr(np, "load", lambda *a, **k: pytest.fail("the archive was inflated"))
    rc, out, err = run_cli(["inverse", "exo5-3d", f, "--max-memory", "500M"])
    assert rc == 2 and "2000000 sample(s)" in err and "over the memory limit" in err, err


@pytest.mark.case("F1")
def test_prepare_lagrange_on_50_links_refuses_up_front_as_a_value_error(monkeypatch):
    """prepare() refuses lagrange on 50 links from the estimate alone, starting no derivation (counted,
    not timed: it was 120 s and 3.5 GB; a wall-clock bound of 10 s asserted it before)."""
    from exo_bench import prepare
    from exo_bench.lagrange import BudgetExceeded
    from exo_bench.lagrange import derivation, numeric

    monkeypatch.setattr(numeric, "compile_equations", lambda *a, **k: pytest.fail("a compilation was started"))
    monkeypatch.setattr(derivation, "_derive_symbolic", lambda *a, **k: pytest.fail("a derivation was started"))
    with pytest.raises(ValueError, match=r"needs about .* and 1034 s .*its derivation alone over the budget of 120 s"):
        prepare(chain(50, 2), "lagrange")
    assert issubclass(BudgetExceeded, ValueError)


@pytest.mark.parametrize(
    "options,needle",
    [
        ({"interrupt": "x"}, "option 'interrupt': expected True or False, got 'x'"),
        ({"budget": float("inf")}, "option 'budget': expected a positive, finite"),
        ({"budget": True}, "option 'budget'"),
    ],
)
def test_lagrange_options_are_checked(options, needle):
    from exo_bench import prepare

    with pytest.raises(ValueError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        prepare(chain(1, 2), "lagrange", **options)


def test_the_cli_default_method_is_prepares_and_the_help_names_it():
    import inspect

    from exo_bench import prepare

    default = inspect.signature(prepare).parameters["method"].default
    assert default == "matrix-factored"
    args = cli.build_parser().parse_args(["inverse", "exo5-3d", "s.json"])
    assert args.method == default
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
        cli.main(["inverse", "--help"])
    assert f"(default: {default}, as prepare()'s;" in " ".join(buf.getvalue().split())


def test_version():
    import exo_bench

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit) as info:
        cli.main(["--version"])
    assert info.value.code == 0 and buf.getvalue().strip() == f"exo-bench {exo_bench.__version__}"


def test_dashes_in_a_link_name_keep_the_urdf_valid(tmp_path):
    import xml.etree.ElementTree as ET

    rc, out, err = run_cli(["urdf", _mech(tmp_path, link2_name="thigh--left-")])
    assert rc == 0 and err == ""
    ET.fromstring(out)  # parses: no "--" inside a comment
    assert '"thigh\\u002d-left-",' in out  # models/files.py xml_comment: json.loads gives the name back


# ------------------------------------------------------------------------------ docs/errors.md
ISSUE_ROWS = {
    "300-link 3D chain": "a 300-link 3D chain with the default method: killed for memory, or a raw MemoryError",
    "lagrange": "a 50-link chain with --method lagrange: BudgetExceeded traceback after 120 s",
    "matrix-paper": "--method matrix-paper on a 3D model: wrong forces with nothing on stderr",
    "0 samples": "a scene whose motion has 0 samples: an internal numpy error",
    "t not increasing": "a states file whose t is not increasing: accepted silently",
    "negative g": "a negative g: accepted silently",
    "masses of 1e308": "masses of 1e308: accepted, all-null output",
    "--reports naming a file": "--reports naming a file: [Errno 17] File exists",
    "binary file": "a binary file as mechanism or states: a decode error that does not name the file",
    "ragged rows": "ragged rows in states: 'expected numbers, got list'",
    "parent on link 1": "a bad parent on link 1: the range reads (0..-1)",
}
OTHER_ROWS = [
    (
        "an np.matrix (or another ndarray subclass, shape or layout than the kernel's) as out, with check=True or "
        "check=False, made the compiled kernels write past the buffer (heap corruption, exit 134/139)",
        "tests/test_array_gate.py::test_np_matrix_and_other_subclasses_as_out_are_refused_naming_out, "
        "test_no_form_of_an_array_corrupts_memory_or_goes_unnamed_in_a_child_process",
    ),
    (
        "exo-bench run SCENE overwrote summary.md with that scene alone",
        "tests/test_run_ids.py::test_running_one_scene_keeps_every_other_scenes_rows, "
        "test_a_folder_from_before_run_identifiers_keeps_its_rows",
    ),
    (
        "Ctrl-C or SIGTERM during run left a folder mixing two runs, unannounced",
        "tests/test_runner.py::test_interrupted_run_leaves_nothing_half_written, "
        "tests/test_run_ids.py::test_a_run_killed_while_publishing_is_announced_and_each_file_marked, "
        "test_every_report_carries_its_run",
    ),
    (
        "a 300-link 3D chain: answer within 2 GB or refuse within 2 s naming a method that fits",
        "tests/test_bad_inputs.py::test_the_300_link_chain_is_refused_with_the_default_limit_before_any_work, "
        "test_the_300_link_chain_answers_within_2_gb_with_a_method_that_fits",
    ),
]


#: Issue 26, case by case: (what was reported, how it answers now, the tests). Items 1 and 3 and
#: "qd=None" / Pinocchio's bias forces on 0 samples of item 6 are the prepared models' (their own tests).
ISSUE_26_ROWS = [
    (
        "2. `urdf -o` replaced a FIFO or a device node with a regular file",
        "refused in one line (exit 2) by the one writer behind every -o/--reports (bench/output/files.py); FIFOs, "
        "devices, sockets and symlinks (to anything: issue 34 S4) are never replaced or written through",
        "test_bad_input[urdf-output-fifo], [urdf-output-link-to-fifo], [urdf-output-dangling-link], [mjcf-output-fifo], "
        "[equations-output-fifo], [reports-fifo], test_nothing_replaces_a_fifo_for_any_command_that_writes, "
        "test_a_symlink_to_a_regular_file_is_refused_and_the_file_kept",
    ),
    (
        "4. `equations --size-report` replaced the `--full` equations_size.md; `stability` overwrote a `--full` "
        "stability.md",
        "a quick run writes `<name>-quick.<ext>` beside a `--full` run's report (runs.json or the "
        "report's own provenance line), as the benchmark reports do",
        "test_a_quick_size_report_never_replaces_a_full_one, test_stability_reports_of_a_full_run_get_quick_names_beside_them",
    ),
    (
        '4. a refused scene in `run`: exit 1, nothing on stderr, good rows replaced by "(scene failed)"',
        "one line on stderr, exit 2; the scene's earlier rows and files are kept (a run where nothing ran leaves the "
        "folder untouched)",
        "test_bad_input[scene-refused], test_a_refused_scene_keeps_the_earlier_rows_and_files_byte_for_byte, "
        "test_a_scene_failing_midway_keeps_its_rows_while_the_others_are_updated",
    ),
    (
        "5. recurrence on a 1000-link 2D chain: estimated 537 MB, measured 10.6 GB",
        "its increment tables are in the cost model, and are now built in one array (peak 10.6 GB -> 3.0 GB): about 3.5 GB and 20 s, refused under --max-memory 1G",
        "test_bad_input[recurrence-1000-2d], tests/test_estimate_vs_measured.py",
    ),
    (
        "5. a 7 MB compressed .npz decompressed to 7.2 GB before any check",
        "judged by its arrays' uncompressed size from the zip directory and .npy headers, before anything is inflated",
        "test_bad_input[npz-bomb], test_a_compressed_npz_is_judged_before_it_is_inflated",
    ),
    (
        "5. `--max-time` left out reading and writing the states",
        "reading (JSON by its size, before parsing; .npz from its headers) and writing tau count in the estimate",
        "test_bad_input[max-time-reading], [max-time-writing]",
    ),
    (
        '5. `prepare(chain(50), "lagrange")`: 120 s and 3.5 GB, then BudgetExceeded (not a ValueError)',
        "refused up front by the estimate, a ValueError naming it and the budget; BudgetExceeded is a ValueError",
        "test_bad_input[lagrange-50], test_prepare_lagrange_on_50_links_refuses_up_front_as_a_value_error",
    ),
    (
        "5. the estimate against measurement",
        "within 2x of peak memory and time across n (error model in the test)",
        "tests/test_estimate_vs_measured.py",
    ),
    ("6. JSON `true` taken as 1.0", "refused, naming the field, sample and column", "test_bad_input[states-json-true]"),
    (
        "6. duplicate JSON keys: the last won silently",
        "refused (every JSON the suite reads)",
        "test_bad_input[states-duplicate-key], [mechanism-duplicate-key]",
    ),
    (
        "6. a NUL or `--` in a link name broke the URDF",
        "control characters refused, naming the link and field; `--` is written `- -` in the URDF's comment",
        "test_bad_input[mechanism-name-nul], [mechanism-name-dashes], test_dashes_in_a_link_name_keep_the_urdf_valid",
    ),
    (
        "6. a gait with T = 1e-300: 12 numpy warnings, exit 0",
        "refused at load, naming motion.gait.T",
        "test_bad_input[scene-gait-period]",
    ),
    (
        "6. a scene named `a/b` silently wrote no .md",
        "refused at load, naming the field",
        "test_bad_input[scene-name-slash]",
    ),
    (
        '6. a dangling --reports symlink: "File exists"',
        "one line naming the link and its missing target",
        "test_bad_input[reports-dangling-link]",
    ),
    (
        "6. `.staging-*` folders stayed forever after a SIGKILL",
        "the next run into the folder removes those whose process is gone (a warning line) and names those it "
        "cannot tell",
        "test_stale_staging_folders_are_removed_by_the_next_run_and_live_ones_reported",
    ),
    (
        "6. `interrupt='x'` taken as True; `budget=inf` raised OverflowError",
        "ValueError naming the option (a budget is finite)",
        "test_lagrange_options_are_checked",
    ),
    (
        "6. `--budget` on a non-lagrange method silently ignored",
        "refused in one line",
        "test_bad_input[budget-other-method]",
    ),
    (
        "6. the CLI `inverse` defaulted to pinocchio, prepare() to matrix-factored; --help named neither",
        "both matrix-factored, named in --help",
        "test_the_cli_default_method_is_prepares_and_the_help_names_it",
    ),
    ("6. no `--version`", "`exo-bench --version` prints the version", "test_version"),
]


def _line(case: Case, tmp: Path) -> tuple[str, str]:
    import re

    rc, out, err, argv = run_case(case, tmp)
    lines = err.strip().splitlines()
    # the line of the case (a result's stderr may also hold warnings that Python's recorder takes under pytest)
    line = next(
        (ln for ln in lines if case.needle and case.needle in ln.replace(str(tmp), "<dir>")),
        lines[0] if lines else "(nothing: exit 0)",
    )
    # times measured by the run itself vary: the document shows them as "..."
    line = re.sub(
        r"\(stopped after [0-9.]+ s\)(; an earlier attempt ran [0-9.]+ s without finishing)?",
        "(stopped after ... s)",
        line,
    )
    line = re.sub(r"[0-9.]+ GB of memory available", "... GB of memory available", line)  # this machine's
    shown = [a.replace(str(tmp), "<dir>") for a in argv]
    line = line.replace(str(tmp), "<dir>")
    example = case.example or "exo-bench " + " ".join(
        a if a and " " not in a and "\0" not in a else repr(a) for a in shown
    )
    return example, line


def render(tmp: Path) -> str:
    def esc(s: str) -> str:
        return s.replace("|", "\\|").replace("\0", "\\0")

    lines = [
        "# What exo-bench says to bad input",
        "",
        "_Generated by `python tests/test_bad_inputs.py` from the cases of tests/test_bad_inputs.py, which also "
        "check every line below (`test_errors_md_is_current` fails when this file is stale)._",
        "",
        "Every error is one line on stderr and exit code 2; no command prints a traceback "
        "(tests/test_fuzz_cli.py drives every subcommand with generated bad input to hold this). Warnings are one "
        "line each and the result is still written (exit 0). Paths under the test's folder read `<dir>`.",
        "",
        "Choices made: a negative `g` is refused (g is the magnitude of gravity, which acts along -y in 2D and "
        "-z in 3D); `-0.0` is accepted as 0. A motion needs at least 2 samples and strictly increasing times. "
        "Masses, lengths and rates whose forces could overflow float64 (a bound above 1e300, "
        "`models.mechanism.force_scale_log10`) are refused. Memory and time are estimated before any work "
        "(exo_bench/api/cost_model.py), reading the states and writing the forces included (a .npz by its uncompressed "
        "size, from its headers); the memory limit is 80 % of the available memory unless `--max-memory` says "
        "otherwise. Files are written only over a regular file or nothing (FIFOs, devices, sockets and any "
        "symlink are refused), and a quick run writes `<name>-quick.<ext>` beside a `--full` run's "
        "report rather than over it.",
        "",
        "| input | exit | what the user sees | example | test |",
        "|---|---|---|---|---|",
    ]
    for case in CASES:
        example, line = _line(case, tmp / case.id)
        lines.append(
            f"| {esc(case.kind)} | {case.rc} | `{esc(line)}` | `{esc(example)}` | "
            f"tests/test_bad_inputs.py::test_bad_input[{case.id}] |"
        )
    lines += ["", "## The rows of issue 16", "", "| reported | covered by |", "|---|---|"]
    for key, text in ISSUE_ROWS.items():
        ids = [c.id for c in CASES if c.issue == key]
        lines.append(f"| {esc(text)} | " + ", ".join(f"test_bad_input[{i}]" for i in ids) + " |")
    for text, tests in OTHER_ROWS:
        lines.append(f"| {esc(text)} | {tests} |")
    lines += [
        "",
        "## The cases of issue 26 (items 2, 4, 5 and 6)",
        "",
        "| reported | now | covered by |",
        "|---|---|---|",
    ]
    for text, now, tests in ISSUE_26_ROWS:
        lines.append(f"| {esc(text)} | {esc(now)} | {tests} |")
    lines += [
        "",
        "## The findings of issue 34",
        "",
        "Each finding of the probe of a fresh clone, with the tests that reproduce it (tests/issue34.py reads "
        "them from the `case` marks; the answer now is the first test's docstring).",
        "",
        "| id | found | now | covered by |",
        "|---|---|---|---|",
    ]
    marked = issue34.marked_tests()
    for ident, text in issue34.FINDINGS.items():
        tests = marked.get(ident, [])
        now = next((summary for _, summary in tests if summary), "")
        names = ", ".join(name for name, _ in tests) or "**no test yet: open**"
        lines.append(f"| {ident} | {esc(text)} | {esc(now)} | {names} |")
    return "\n".join(lines) + "\n"


def test_errors_md_is_current(tmp_path):
    assert DOC.exists(), "docs/errors.md is missing: run python tests/test_bad_inputs.py"
    assert DOC.read_text() == render(tmp_path), "docs/errors.md is stale: run python tests/test_bad_inputs.py"


def test_every_issue_row_has_a_test():
    for key in ISSUE_ROWS:
        assert any(c.issue == key for c in CASES), key
    for _, tests in OTHER_ROWS + [(a, c) for a, _, c in ISSUE_26_ROWS]:
        for name in tests.split(", "):
            if name.startswith("[") or name.startswith("test_bad_input["):
                ident = name.split("[", 1)[1].rstrip("]")
                assert any(c.id == ident for c in CASES), name
                continue
            if name.endswith(".py"):
                assert (ROOT / name).exists(), name
                continue
            path, func = name.split("::") if "::" in name else (None, name)
            assert any(f"def {func}(" in p.read_text() for p in (ROOT / "tests").glob("test_*.py")), name


def test_every_issue_34_finding_has_a_test():
    """Every finding of issue 34 (tests/issue34.py) has at least one test marked with its id, and no test
    carries an id the catalogue does not know."""
    marked = issue34.marked_tests()
    assert not [k for k in issue34.FINDINGS if not marked.get(k)], "findings without a test"
    assert not set(marked) - set(issue34.FINDINGS), "unknown finding ids"


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        DOC.write_text(render(Path(d)))
    print(f"wrote {DOC}")
