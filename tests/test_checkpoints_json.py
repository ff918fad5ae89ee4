"""Issue 34, S3, T3, D8: what the suite reads back from disk is data, checked before any work.

Nothing read from disk is unpickled: the stability study's checkpoints are tagged JSON
(bench/cluster/checkpoints.py) that builds only the study's result types; a planted pickle is
never read. Every JSON file read back (a sweep's checkpoints, a reports folder's ``runs.json``) has
its shape checked first, and anything else is one line naming the file and the field.
"""

from __future__ import annotations

import ast
import contextlib
import io
import json
import math
import os
import pickle
from pathlib import Path

import numpy as np
import pytest
from cli_runs import run_cli

from exo_bench.bench.output.provenance import REPO

# ------------------------------------------------------------------------------ nothing unpickled
#: Calls that run code from what they read (``module.function``); ``numpy.load`` only without
#: ``allow_pickle=False``, ``yaml.load`` only without a safe loader.
UNSAFE = {
    ("pickle", "load"),
    ("pickle", "loads"),
    ("pickle", "Unpickler"),
    ("dill", "load"),
    ("dill", "loads"),
    ("cloudpickle", "load"),
    ("cloudpickle", "loads"),
    ("joblib", "load"),
    ("shelve", "open"),
    ("torch", "load"),
    ("pd", "read_pickle"),
    ("pandas", "read_pickle"),
    ("marshal", "loads"),
    ("marshal", "load"),
}


def _package_sources() -> list[Path]:
    skip = {".venv", "tests", "docs", ".git", "build", "dist", "reports"}
    return [
        p
        for p in REPO.rglob("*.py")
        if not (set(p.relative_to(REPO).parts[:-1]) & skip) and not p.relative_to(REPO).parts[0].startswith(".")
    ]


def _unsafe_calls(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)):
            continue
        f = node.func
        base = f.value.id if isinstance(f.value, ast.Name) else None
        keywords = {k.arg: k.value for k in node.keywords}
        where = f"{path.relative_to(REPO)}:{node.lineno}"
        if (base, f.attr) in UNSAFE:
            found.append(f"{where} {base}.{f.attr}")
        elif base in ("np", "numpy") and f.attr == "load":
            flag = keywords.get("allow_pickle")
            if not (isinstance(flag, ast.Constant) and flag.value is False):
                found.append(f"{where} {base}.load without allow_pickle=False")
        elif base == "yaml" and f.attr in ("load", "load_all", "unsafe_load"):
            loader = keywords.get("Loader")
            if not (isinstance(loader, ast.Attribute) and loader.attr in ("SafeLoader", "CSafeLoader")):
                found.append(f"{where} yaml.{f.attr} without a safe loader")
    return found


@pytest.mark.case("S3")
def test_nothing_in_the_package_unpickles_what_it_reads():
    """No module of the package calls pickle/dill/cloudpickle/joblib/shelve/marshal/torch loaders,
    ``pandas.read_pickle``, ``yaml.load`` without a safe loader or ``numpy.load`` without
    ``allow_pickle=False`` (the stability checkpoints were pickles)."""
    sources = _package_sources()
    assert len(sources) > 50 and any(p.name == "commands.py" for p in sources)
    found = [c for p in sources for c in _unsafe_calls(p)]
    assert found == []


class _Payload:
    """A pickle that runs code when loaded: it creates the file ``marker``."""

    def __init__(self, marker: Path):
        self.marker = marker

    def __reduce__(self):
        return (os.system, (f"touch {self.marker}",))


def _family():
    from exo_bench.bench.studies.stability import cases, evaluation
    from exo_bench.models.mechanism.presets import exo5

    mech = exo5(3)
    q = np.linspace(-1, 1, 2 * mech.dof).reshape(2, mech.dof)
    case = cases.Case("baseline", "exo5-3d", "s0", 0.5, mech, q, q * 2, q * 3)
    rows = {
        "pinocchio": evaluation.MethodRow("pinocchio", abs_err=1e-16, rel_err=2e-17, seconds=0.25),
        "lagrange": evaluation.MethodRow("lagrange", status="skipped", reason="over budget"),
    }
    cr = evaluation.CaseResult(case, "Lagrange, mpmath 50 digits", rows, 12.5, math.inf, 3.0, ["sample 0: l2 = 0"], 1)
    return evaluation.FamilyResult("baseline", "the doc", [cr], 1.5, {"lagrange": "why"}, "mass warning")


def _forward():
    from exo_bench.bench.studies.stability import cases, forward_evaluation as fe
    from exo_bench.bench.studies.stability import forward_round_trip as frt
    from exo_bench.models.simulation.forward_dynamics import Simulation

    sim = Simulation("DOP853", 1e-6, 1e-9, np.array([0.0, 0.5]), np.ones((2, 4)), nfev=10, status="ok")
    sim.solution = lambda t: t  # a dense output: never kept
    return fe.ForwardResults(
        cases.QUICK,
        [fe.TermsRow("exo5-3d", "pinocchio", "exposed", m_rel=1e-15)],
        [fe.SingularDemo("l2 = 0", "finite", "refused: link 2")],
        {"gait": 1.5},
        [frt.RoundTrip("gait", "pinocchio", "DOP853", 1e-6, sim, error=1e-7)],
        [],
        [("gait", "over budget")],
        [fe.EnergyRun("spring", "Radau", 1e-6, sim, drift=math.nan)],
        [fe.StiffRun("stiff", "BDF", 1e-3, sim, 1e3, cond=-math.inf)],
        [],
        {"gait": "a gait"},
        2.0,
        ["note"],
    )


@pytest.mark.case("S3")
def test_stability_checkpoints_are_json_and_a_planted_pickle_never_runs(tmp_path, monkeypatch):
    """``stability --full`` reads its checkpoints as JSON of the study's own result types; pickles
    planted in the checkpoint folder (under the parts' names or any other) are never loaded, so
    their code never runs, and no cluster is started when every part is checkpointed."""
    from exo_bench.bench.cluster import commands
    from exo_bench.bench.cluster.checkpoints import checkpoint_dir, default_checkpoints, save_part
    from exo_bench.bench.perf import rows as _rows
    from exo_bench.bench.studies.options import StabilityOptions
    from exo_bench.bench.studies.stability import cases

    monkeypatch.setattr(commands, "code_key", lambda: "c0de")  # the checkout's own may change meanwhile
    reports = tmp_path / "reports"
    folder = checkpoint_dir(default_checkpoints(reports), "c0de")
    folder.mkdir(parents=True)
    methods = ["pinocchio"]
    marker = tmp_path / "pwned"
    parts = [f"family:{n}" for n in cases.FAMILIES] + ["forward"]
    for part in parts:
        tag = _rows.safe_name(f"stability:{cases.QUICK.name}:{','.join(methods)}:{part}")
        for name in (f"{tag}.pickle", f"{tag}.pkl", f"{tag}.json.pickle", "x.pickle"):
            (folder / name).write_bytes(pickle.dumps(_Payload(marker)))
        value = (_forward(), []) if part == "forward" else (_family(), [("IllConditionedWarning", "w")])
        save_part(folder, tag, value)

    def no_cluster(*a, **k):
        raise AssertionError("a cluster was started although every part is checkpointed")

    monkeypatch.setattr(commands, "cluster", no_cluster)
    evaluate = commands.stability_evaluator(StabilityOptions(reports=reports, full=True))
    with pytest.warns(Warning, match="^w$"):  # the checkpointed warnings, issued again
        families, forward = evaluate(cases.QUICK, methods, lambda msg: None)
    assert not marker.exists()
    assert len(families) == len(cases.FAMILIES) and families[0].results[0].rows["pinocchio"].rel_err == 2e-17
    assert forward.profile == cases.QUICK and forward.round_trips[0].sim.solution is None


@pytest.mark.case("S3")
def test_a_result_round_trips_through_json_bit_for_bit():
    """Encoding a family's and the forward part's results and decoding them gives the same values:
    the same array bits, tuples as tuples, NaN and infinities, the same mechanism."""
    from exo_bench.bench.cluster import checkpoints as codec

    for value in (_family(), _forward()):
        data = json.loads(json.dumps(codec.encode(value), allow_nan=False))
        back = codec.decode(data)
        assert type(back) is type(value)
        assert codec.encode(back) == codec.encode(value)
    fam = codec.decode(json.loads(json.dumps(codec.encode(_family()))))
    case = fam.results[0].case
    assert case.mechanism == _family().results[0].case.mechanism and case.q.dtype == np.float64
    assert np.array_equal(case.qdd, _family().results[0].case.qdd) and math.isinf(fam.results[0].cond_eq)


@pytest.mark.case("S3")
@pytest.mark.parametrize(
    "value, field",
    [
        ({"$dataclass": "Popen", "fields": {}}, "value"),  # not a result type
        ({"$dataclass": "MethodRow", "fields": {"method": "x"}}, "value"),  # fields missing
        ({"$array": ["|O", [1], "AA=="]}, "value"),  # an object array
        ({"$float": "1e308"}, "value"),
        ({"__reduce__": ["os.system", ["id"]]}, "value"),
    ],
)
def test_a_part_of_another_shape_is_refused_naming_the_field(tmp_path, value, field):
    """A checkpointed part that is not one of the study's result types (another class, missing
    fields, an object array, any other object) is one ValueError naming the file and the field."""
    from exo_bench.bench.cluster import checkpoints as codec
    from exo_bench.bench.cluster.checkpoints import load_part

    (tmp_path / "t.json").write_text(json.dumps({"format": codec.FORMAT, "key": "t", "value": value}))
    with pytest.raises(ValueError, match=rf"t\.json: field '{field}'"):
        load_part(tmp_path, "t", "FamilyResult")


@pytest.mark.case("S3")
def test_a_field_of_another_type_is_refused_naming_it(tmp_path):
    """A result's field of another type than its declaration (a string for a float) is refused,
    naming the field's path in the file."""
    from exo_bench.bench.cluster import checkpoints as codec
    from exo_bench.bench.cluster.checkpoints import load_part

    data = json.loads(codec.part_text("t", (_family(), [])))
    data["value"]["$tuple"][0]["fields"]["seconds"] = "fast"
    (tmp_path / "t.json").write_text(json.dumps(data))
    with pytest.raises(ValueError, match=r"t\.json: field 'value\[0\]\.seconds': expected float, got str"):
        load_part(tmp_path, "t", "FamilyResult")


# ------------------------------------------------------------------------------ a sweep's row checkpoints
@pytest.mark.case("T3")
@pytest.mark.parametrize(
    "content, says",
    [
        ("[]", "the top level: expected an object, got a list"),
        ('"ok"', "the top level: expected an object, got a string"),
        ("3", "the top level: expected an object, got a number"),
        ("null", "expected an object, got null"),
        ('{"key": "k", "status": "ok", "benchmark_json": []}', "field 'benchmark_json': expected an object or null"),
        ('{"key": "k", "status": "ok", "skips": {"a": 1}}', "field 'skips': expected a list"),
        ('{"key": "k", "status": "ok", "benchmark_json": {"benchmarks": [3]}}', "field 'benchmark_json.benchmarks[0]'"),
        ('{"key": "k", "status": 7}', "field 'status': expected a string, got a number (7)"),
        ("{not json", "not valid JSON"),
    ],
)
def test_a_row_checkpoint_of_another_shape_is_refused_naming_the_file(tmp_path, content, says):
    """A sweep's row checkpoint of valid JSON that is not a row's record (not an object, a field of
    another type) is one ValueError naming the file and the field, not an internal AttributeError."""
    from exo_bench.bench.cluster.checkpoints import load_checkpoint
    from exo_bench.bench.perf import rows as _rows

    p = tmp_path / f"{_rows.safe_name('k')}.json"
    p.write_text(content)
    with pytest.raises(ValueError) as e:
        load_checkpoint(tmp_path, "k")
    assert str(p) in str(e.value) and says in str(e.value) and "remove the file" in str(e.value), str(e.value)


def test_a_good_row_checkpoint_is_read():
    """A record as ``run_row`` writes it is read back (and another row's is not used)."""
    import tempfile

    from exo_bench.bench.cluster.checkpoints import load_checkpoint
    from exo_bench.bench.perf import rows as _rows

    rec = {
        "key": "k",
        "nodeids": ["a::b"],
        "host": "h",
        "cpu": "c",
        "status": "ok",
        "reason": "",
        "seconds": 1.5,
        "benchmark_json": {"benchmarks": [{"fullname": "a::b", "stats": {}}], "machine_info": {}},
        "skips": [{"nodeid": "a::c", "reason": "r", "params": []}],
        "machine_info": None,
        "inherited": [],
    }
    with tempfile.TemporaryDirectory() as d:
        (Path(d) / f"{_rows.safe_name('k')}.json").write_text(json.dumps(rec))
        assert load_checkpoint(Path(d), "k") == rec
        assert load_checkpoint(Path(d), "other") is None


# ------------------------------------------------------------------------------ runs.json


@pytest.mark.case("D8")
@pytest.mark.parametrize(
    "manifest, field",
    [
        ({"format": 1, "runs": []}, "runs"),
        ({"format": 1, "runs": {"r": "x"}}, "runs.r"),
        ({"format": 1, "runs": {}, "scenes": {"s": {"run": "r", "rows": "abc"}}}, "scenes.s.rows"),
        ({"format": 1, "runs": {}, "files": {"a.md": ["r"]}}, "files.a.md"),
        ({"format": 1, "runs": {"r": {"status": 3}}}, "runs.r.status"),
    ],
)
def test_a_runs_json_of_wrong_types_is_refused_before_any_work(tmp_path, monkeypatch, manifest, field):
    """A reports folder's runs.json of format 1 with fields of other types is refused before any
    work, in one line naming the file and the field (exit 2); it was an internal AttributeError
    after all the work, throwing the run away."""
    from exo_bench.bench.cli import run as run_cmd

    def no_work(*a, **k):
        raise AssertionError("a scene ran")

    monkeypatch.setattr(run_cmd, "run_scene", no_work)
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "runs.json").write_text(json.dumps(manifest))
    rc, out, err = run_cli(["run", "fig2a-2d", "--reports", rep])
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{rep / 'runs.json'}: field {field!r}" in err and "internal error" not in err, err
    assert sorted(p.name for p in rep.iterdir()) == ["runs.json"]


@pytest.mark.case("D8")
def test_the_publisher_refuses_a_runs_json_of_wrong_types_naming_it(tmp_path):
    """``read_manifest`` (under the reports folder's lock) refuses a runs.json of format 1 whose
    fields have other types, naming the file and the field; a well-formed one is read as it is."""
    from exo_bench.bench.output.publish import read_manifest

    (tmp_path / "runs.json").write_text(json.dumps({"format": 1, "runs": {}, "files": {"a": 3}}))
    with pytest.raises(ValueError, match=r"runs\.json: field 'files\.a': expected an object, got a number"):
        read_manifest(tmp_path)
    good = {"format": 1, "runs": {"r": {"command": "c", "status": "complete"}}, "scenes": {}, "files": {}}
    (tmp_path / "runs.json").write_text(json.dumps(good))
    assert read_manifest(tmp_path) == good


# ------------------------------------------------------------------------------ any JSON at all
def _json_values():
    from hypothesis import strategies as st

    leaves = st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=5)
    return st.recursive(
        leaves, lambda kids: st.lists(kids, max_size=3) | st.dictionaries(st.text(max_size=8), kids, max_size=4)
    )


def _near(fields: dict):
    """Objects with the real fields' names and any values: what a hand-edited file looks like."""
    from hypothesis import strategies as st

    return st.fixed_dictionaries({}, optional={k: _json_values() for k in fields})


@pytest.mark.case("T3", "D8")
def test_any_json_read_back_is_used_or_refused_in_one_line(tmp_path_factory):
    """Any JSON at all, as a row checkpoint, a stability part or a reports folder's runs.json, is
    either read or refused with a ValueError naming the file; never another exception."""
    from hypothesis import given, settings, strategies as st

    from exo_bench.bench.cluster.checkpoints import ROW_SHAPE, load_checkpoint, load_part
    from exo_bench.bench.output.publish import read_manifest
    from exo_bench.bench.perf import rows as _rows

    d = tmp_path_factory.mktemp("any")
    row = d / f"{_rows.safe_name('k')}.json"
    manifest = {"format": 1, "runs": None, "scenes": None, "files": None}

    @settings(max_examples=300, deadline=None)
    @given(
        value=_json_values() | _near(ROW_SHAPE) | _near(manifest).map(lambda m: {**m, "format": 1}),
        part=_json_values()
        | st.builds(lambda v: {"format": "exo-bench stability checkpoint 1", "key": "t", "value": v}, _json_values()),
    )
    def check(value, part):
        text = json.dumps(value)
        for path, read in (
            (row, lambda: load_checkpoint(d, "k")),
            (d / "runs.json", lambda: read_manifest(d)),
        ):
            path.write_text(text)
            try:
                read()
            except ValueError as e:
                assert str(path) in str(e)
        (d / "t.json").write_text(json.dumps(part))
        try:
            load_part(d, "t", "FamilyResult")
        except ValueError as e:
            assert str(d / "t.json") in str(e)

    with contextlib.redirect_stderr(io.StringIO()):  # read_manifest's warning for other formats
        check()
