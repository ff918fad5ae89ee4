"""No traceback from any command: every subcommand driven with generated bad input (hypothesis).

The property, for every generated command line: ``exo_bench.bench.cli.main`` returns (never
raises); the exit code is 0 (a result), 1 (``run``: a scene failed, reported) or 2 (refused); stderr
has no traceback and no "internal error"; a refusal is exactly one line on stderr and nothing on
stdout; a result's stderr lines are warnings. Inputs: JSON values of every kind, mutated mechanism
and state files, shapes and numbers (NaN, inf, 1e308, -0.0, 5e-324, integers too large for a float),
huge n, file kinds (missing, folder, binary, empty, device, FIFO, NUL in the name, too long, nested
too deeply), option values and free-form argument lists. Runs in-process for speed (a few runs go
through a subprocess at the end), in a temporary working folder; the heavy suite jobs (``bench``,
``errata``, ``stability``, a whole ``run``) are replaced by stubs in the free-form test so that a
generated valid command does not start them.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from cli_runs import cli_process, run_cli

from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain, exo5, fig1

FUZZ = settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)

SPECIAL = [
    math.nan,
    math.inf,
    -math.inf,
    1e308,
    -1e308,
    -0.0,
    0.0,
    5e-324,
    1e-308,
    1e200,
    -1e200,
    10**400,
    -(10**400),
    0.5,
    1.0,
    2,
    True,
    False,
    None,
    "1",
    "",
    [],
    {},
]
numbers = st.sampled_from(SPECIAL) | st.floats(allow_nan=True, allow_infinity=True) | st.integers(-(10**30), 10**30)
json_values = st.recursive(
    st.none() | st.booleans() | numbers | st.text(max_size=6),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4),
    max_leaves=12,
)


@contextmanager
def workdir():
    """A fresh temporary working folder (the CLI's default reports folder is ./reports)."""
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as d:
        os.chdir(d)
        try:
            yield Path(d)
        finally:
            os.chdir(cwd)


def holds(argv, allow=(0, 2)) -> tuple[int, str, str]:
    """Run ``exo-bench argv`` and assert the property of the module docstring."""
    rc, out, err = run_cli([str(a) for a in argv])
    assert "Traceback" not in err and "internal error" not in err, (argv, err)
    assert rc in allow, (argv, rc, err)
    lines = err.strip().splitlines()
    if rc == 2:
        assert len(lines) == 1 and out == "", (argv, err)
        assert lines[0].startswith("exo-bench"), (argv, err)
    elif argv and argv[0] == "inverse":
        assert all(line.startswith("exo-bench: warning: ") for line in lines), (argv, err)
        json.loads(out)
    return rc, out, err


def _dump(value) -> str:
    return json.dumps(value, allow_nan=True)


def _good_states(d: Path, mech=None) -> Path:
    mech = mech or exo5(3)
    q, qd, qdd = random_states(mech, 2, 0)
    (d / "good.json").write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
    return d / "good.json"


# ------------------------------------------------------------------------------ inverse: the mechanism
@FUZZ
@given(json_values)
def test_inverse_with_any_json_as_mechanism(value):
    with workdir() as d:
        (d / "m.json").write_text(_dump(value))
        holds(["inverse", d / "m.json", _good_states(d)])


MECH_FIELDS = ["dim", "g", "links", "name", "extra"] + [
    f"link{i}_{k}" for i in (1, 3) for k in ("parent", "sign", "masses", "n", "name", "extra")
]


@FUZZ
@given(st.sampled_from(MECH_FIELDS), json_values | st.lists(numbers, min_size=3, max_size=3))
def test_inverse_with_one_field_of_the_mechanism_replaced(field, value):
    data = exo5(3).to_dict()
    if field.startswith("link") and field[4].isdigit():
        i, key = field[4:].split("_", 1)
        data["links"][int(i) - 1][key] = value
    else:
        data[field] = value
    with workdir() as d:
        (d / "m.json").write_text(_dump(data))
        holds(["inverse", d / "m.json", _good_states(d), "--method", "matrix-factored"])


def _special_id(v) -> str:
    text = repr(v)
    return text if len(text) < 12 else text[:8] + f"..({len(text)})"


@pytest.mark.parametrize("value", SPECIAL, ids=_special_id)
@pytest.mark.parametrize("field", MECH_FIELDS)
def test_every_special_value_in_every_mechanism_field(field, value):
    """Deterministic: every special value in every field (hypothesis samples; this covers each once)."""
    test_inverse_with_one_field_of_the_mechanism_replaced.hypothesis.inner_test(field, value)


@pytest.mark.parametrize("value", SPECIAL, ids=_special_id)
@pytest.mark.parametrize("which", ["q", "qd", "qdd"])
def test_every_special_value_in_the_states(which, value):
    mech = exo5(3)
    q, qd, qdd = random_states(mech, 2, 1)
    arrays = {"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}
    arrays[which][1][12] = value  # l3 in q
    with workdir() as d:
        (d / "s.json").write_text(_dump(arrays))
        holds(["inverse", "exo5-3d", d / "s.json", "--method", "matrix-factored"])


# ------------------------------------------------------------------------------ inverse: the states
@FUZZ
@given(
    st.sampled_from(["fig1-2d", "exo5-3d"]),
    st.integers(0, 3),
    st.sampled_from([-1, 0, 1]),
    st.lists(numbers, min_size=1, max_size=8),
    st.sampled_from(["q", "qd", "qdd"]),
    st.sampled_from(["pinocchio", "matrix-factored", "matrix", "recurrence", "matrix-paper"]),
)
def test_inverse_with_generated_shapes_and_numbers(preset, samples, extra, values, which, method):
    mech = fig1(2) if preset == "fig1-2d" else exo5(3)
    q, qd, qdd = random_states(mech, max(samples, 1), 1)
    arrays = {"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}
    cols = mech.dof + extra
    rows = [[values[(r * cols + c) % len(values)] for c in range(cols)] for r in range(samples)]
    arrays[which] = rows
    with workdir() as d:
        (d / "s.json").write_text(_dump(arrays))
        holds(["inverse", preset, d / "s.json", "--method", method])


@FUZZ
@given(st.dictionaries(st.sampled_from(["q", "qd", "qdd", "t", "x"]), json_values, max_size=4))
def test_inverse_with_any_json_as_states(value):
    with workdir() as d:
        (d / "s.json").write_text(_dump(value))
        holds(["inverse", "fig1-2d", d / "s.json"])


@FUZZ
@given(
    st.sampled_from(["pinocchio", "lagrange", "matrix", "matrix-factored", "matrix-paper", "recurrence", "newton", ""]),
    st.sampled_from(["--max-memory", "--max-time", "--budget"]),
    st.sampled_from(["2G", "0", "-1", "nan", "inf", "1e999", "1e-300", "x", "", "1.5GB", "10k", "-0.0", "3"]),
)
def test_inverse_options(method, option, value):
    with workdir() as d:
        holds(["inverse", "fig1-2d", _good_states(d, fig1(2)), "--method", method, option, value])


# ------------------------------------------------------------------------------ file kinds and paths
def _make(kind: str, d: Path) -> str:
    if kind == "missing":
        return str(d / "none.json")
    if kind == "folder":
        return str(d)
    if kind == "binary":
        (d / "b.json").write_bytes(bytes(range(256)) * 4)
        return str(d / "b.json")
    if kind == "empty":
        (d / "e.json").write_text("")
        return str(d / "e.json")
    if kind == "bom":
        (d / "bom.json").write_bytes(b"\xef\xbb\xbf{}")
        return str(d / "bom.json")
    if kind == "device":
        return "/dev/null"
    if kind == "fifo":
        os.mkfifo(d / "fifo")
        return str(d / "fifo")
    if kind == "nul":
        return "a\0b.json"
    if kind == "long":
        return str(d / ("x" * 300 + ".json"))
    if kind == "deep":
        (d / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
        return str(d / "deep.json")
    if kind == "loop":
        os.symlink(d / "loop", d / "loop")
        return str(d / "loop")
    if kind == "npz-junk":
        (d / "j.npz").write_bytes(b"PK\x03\x04junk")
        return str(d / "j.npz")
    if kind == "under-file":
        (d / "f").write_text("x")
        return str(d / "f" / "x.json")
    raise AssertionError(kind)


KINDS = [
    "missing",
    "folder",
    "binary",
    "empty",
    "bom",
    "device",
    "fifo",
    "nul",
    "long",
    "deep",
    "loop",
    "npz-junk",
    "under-file",
]


@settings(max_examples=len(KINDS) * 4, deadline=None, derandomize=True, database=None)
@given(
    st.sampled_from(KINDS),
    st.sampled_from(
        [
            "mechanism",
            "states",
            "scene",
            "urdf-out",
            "urdf-mechanism",
            "equations-out",
            "equations-mechanism",
            "mjcf-out",
            "mjcf-mechanism",
            "states-out",
            "states-mechanism",
        ]
    ),
)
def test_every_kind_of_file_in_every_role(kind, role):
    with workdir() as d:
        bad = _make(kind, d)
        if role == "mechanism":
            holds(["inverse", bad, _good_states(d)])
        elif role == "states":
            holds(["inverse", "exo5-3d", bad])
        elif role == "scene":
            holds(["run", bad, "--reports", d / "rep"])
        elif role == "urdf-out":
            holds(["urdf", "fig1-2d", "-o", bad])
        elif role == "equations-out":
            holds(["equations", "fig1-2d", "--format", "c", "-o", bad])
        elif role == "equations-mechanism":
            holds(["equations", bad, "--format", "python"])
        elif role == "mjcf-out":
            holds(["mjcf", "fig1-2d", "--no-check", "-o", bad])
        elif role == "mjcf-mechanism":
            holds(["mjcf", bad, "--no-check"])
        elif role == "states-out":
            holds(["states", "fig1-2d", "-o", bad])
        elif role == "states-mechanism":
            holds(["states", bad, "-o", d / "s.json"])
        else:
            holds(["urdf", bad])


@settings(max_examples=30, deadline=None, derandomize=True, database=None)
@given(
    st.sampled_from(["run", "bench", "errata", "stability"]),
    st.sampled_from(["file", "under-file", "nul", "empty", "long"]),
)
def test_report_commands_refuse_a_bad_reports_folder_before_any_work(command, kind):
    with workdir() as d:
        (d / "f").write_text("x")
        path = {
            "file": d / "f",
            "under-file": d / "f" / "sub",
            "nul": "r\0p",
            "empty": "",
            "long": d / ("y" * 300) / "z",
        }[kind]
        argv = [command] + (["fig1-2d"] if command == "run" else []) + ["--reports", path]
        rc, _, _ = holds(argv)
        assert rc == 2


# ------------------------------------------------------------------------------ huge n
@pytest.mark.parametrize("n,dim", [(2000, 2), (20000, 3)])
@pytest.mark.parametrize("method", ["pinocchio", "lagrange", "matrix", "matrix-factored", "recurrence"])
def test_huge_n_is_answered_or_refused_in_one_line(n, dim, method, tmp_path):
    m = chain(n, dim)
    (tmp_path / "c.json").write_text(m.to_json(indent=None))
    q, qd, qdd = random_states(m, 1, 0)
    (tmp_path / "s.json").write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
    rc, _, err = holds(
        [
            "inverse",
            tmp_path / "c.json",
            tmp_path / "s.json",
            "--method",
            method,
            "--max-memory",
            "2G",
            "--max-time",
            "20",
        ]
    )
    if method in ("pinocchio", "lagrange") or n == 20000:
        assert rc == 2 and "needs about" in err


# ------------------------------------------------------------------------------ scenes
SCENE_FIELDS = {
    "mechanism": ['"fig1-2d"', '"none.json"', "3", '""', '"bin.json"'],
    "methods": ['["pinocchio"]', "[]", '["newton"]', '"pinocchio"', "[1]"],
    "reference": ['"matrix"', "1", '"pinocchio"'],
    "outputs": ['["table"]', '["movie"]', "[]", '"table"'],
    "kind": ['"smooth-random"', '"gait"', '"planar-gait"', '"states"', '"jog"', "1"],
    "samples": ["20", "0", "1", "-5", "1e9", "nan", "inf", "10000000000", '"20"', "true"],
    "duration": ["1.0", "0", "-1.0", "nan", "inf", "1e308"],
    "seed": ["0", "-1", "-2", "1.5", "99999999999999999999"],
    "periods": ["1.0", "0.0001", "-1", "nan", "1e300"],
    "samples_per_period": ["40", "0", "1", "-3", "2.5"],
    "file": ['"mo.json"', '"none.json"', '"bin.json"', "[]"],
}


@settings(max_examples=80, deadline=None, derandomize=True, database=None)
@given(
    st.fixed_dictionaries({k: st.sampled_from(v) for k, v in SCENE_FIELDS.items()}),
    st.sets(st.sampled_from(sorted(SCENE_FIELDS)), max_size=11),
)
def test_run_with_generated_scenes(values, present):
    lines_top = [f"{k} = {values[k]}" for k in ("mechanism", "methods", "reference", "outputs") if k in present]
    motion = [
        f"{k} = {values[k]}"
        for k in ("kind", "samples", "duration", "seed", "periods", "samples_per_period", "file")
        if k in present
    ]
    text = "\n".join(lines_top + ["[motion]"] + motion) + "\n"
    with workdir() as d:
        (d / "bin.json").write_bytes(bytes(range(256)))
        q, qd, qdd = random_states(fig1(2), 3, 0)
        (d / "mo.json").write_text(
            json.dumps({"t": [0.0, 0.1, 0.1], "q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()})
        )
        (d / "sc.toml").write_text(text)
        holds(["run", d / "sc.toml", "--reports", d / "rep", "--max-memory", "20M"], allow=(0, 1, 2))


# ------------------------------------------------------------------------------ free-form argument lists
TOKENS = [
    "inverse",
    "urdf",
    "mjcf",
    "--no-check",
    "run",
    "bench",
    "errata",
    "stability",
    "presets",
    "--method",
    "--budget",
    "--max-memory",
    "--max-time",
    "--reports",
    "--full",
    "-o",
    "--output",
    "--update-readme",
    "-h",
    "fig1-2d",
    "exo5-3d",
    "matrix",
    "2G",
    "-1",
    "nan",
    "s.json",
    "m.json",
    "x",
    "",
    "--",
    "-",
    "\0",
    "equations",
    "--format",
    "latex",
    "python",
    "c",
    "--symbolic-parameters",
    "--size-report",
]


@FUZZ
@given(st.lists(st.sampled_from(TOKENS) | st.text(max_size=8), max_size=6))
def test_any_argument_list(argv):
    import exo_bench.bench.perf.reports.benchmark_reports as bench_reports
    import exo_bench.bench.studies.errata as errata
    import exo_bench.bench.cli.run as runner
    import exo_bench.bench.studies.stability.report as stability

    with workdir() as d, pytest.MonkeyPatch.context() as mp:
        for mod in (bench_reports, errata, stability):  # the heavy jobs: stubs
            mp.setattr(mod, "run", lambda options: 0)
        mp.setattr(runner, "run_main_job", lambda options: 0)
        mp.setattr("exo_bench.bench.cluster.commands.bench_run", lambda options: 0)  # bench --full: the Dask sweep
        mp.setattr("exo_bench.bench.studies.equations_size.size_report", lambda options: 0)
        q, qd, qdd = random_states(fig1(2), 2, 0)
        (d / "s.json").write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
        (d / "m.json").write_text(fig1(2).to_json())
        try:
            holds(argv)
        except SystemExit as e:  # argparse's --help prints the help and exits 0
            assert e.code in (0, None) and any(a in ("-h", "--help") for a in argv), (argv, e.code)


# ------------------------------------------------------------------------------ a few real processes
@pytest.mark.parametrize(
    "args,needle",
    [
        (["inverse", "BIN", "exo5-3d"], "expected UTF-8 text"),
        (["inverse", "CHAIN300", "S300"], "matrix-factored fits"),
        (["errata", "--reports", "FILE"], "expected a folder, but it is a file"),
    ],
)
def test_in_a_subprocess_too(args, needle, tmp_path):
    (tmp_path / "bin").write_bytes(bytes(range(256)))
    (tmp_path / "file").write_text("x")
    m = chain(300, 3)
    (tmp_path / "c.json").write_text(m.to_json(indent=None))
    q, qd, qdd = random_states(m, 1, 0)
    (tmp_path / "s.json").write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
    sub = {
        "BIN": tmp_path / "bin",
        "CHAIN300": tmp_path / "c.json",
        "S300": tmp_path / "s.json",
        "FILE": tmp_path / "file",
    }
    argv = [str(sub.get(a, a)) for a in args] + (
        ["--max-memory", "2G", "--method", "pinocchio"] if args[1] == "CHAIN300" else []
    )
    r = cli_process(*argv, cwd=tmp_path)
    assert r.returncode == 2 and r.stdout == "" and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert needle in r.stderr and "Traceback" not in r.stderr


def test_python_warnings_are_one_line_each_in_a_subprocess(tmp_path):
    """matrix-paper divides 0/0 at phi = 0 and warns (RuntimeWarning): on the command line that is one
    line, like every other line on stderr, not Python's two-line warning with a source line."""
    from exo_bench.models.gait.motion import gait

    mo = gait(exo5(3), np.array([0.0, 0.3]))
    (tmp_path / "s.json").write_text(json.dumps({"q": mo.q.tolist(), "qd": mo.qd.tolist(), "qdd": mo.qdd.tolist()}))
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "exo_bench.bench.cli",
            "inverse",
            "exo5-3d",
            str(tmp_path / "s.json"),
            "--method",
            "matrix-paper",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0
    lines = r.stderr.strip().splitlines()
    assert any("divides 0/0" in line for line in lines), r.stderr
    assert all(line.startswith("exo-bench: warning: ") for line in lines), r.stderr
