"""Scene names that cannot collide: with the suite's own reports, with each other, or by spoofing
characters; and scenes that name a method or an output twice."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cli_runs import main_job
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import exo_bench.bench.cli.run as runner
from exo_bench.bench.studies.options import RunOptions
from exo_bench.bench.studies.scenes import load_scene
from exo_bench.models.files import name_problem

CHEAP = """name = {name}
mechanism = "fig1-2d"
methods = {methods}
outputs = {outputs}
[motion]
kind = "smooth-random"
duration = 1.0
samples = 8
"""


def _toml_string(text: str) -> str:
    """``text`` as a TOML basic string: quote, backslash and control characters escaped."""
    esc = lambda c: "\\" + c if c in '"\\' else f"\\u{ord(c):04X}" if ord(c) < 0x20 or ord(c) == 0x7F else c  # noqa: E731
    return '"' + "".join(esc(c) for c in text) + '"'


def _scene(d: Path, name: str, file: str | None = None, methods='["pinocchio"]', outputs='["table"]') -> Path:
    """A cheap scene file named ``name`` (its field ``name``)."""
    p = d / (file or f"{len(list(d.glob('*.toml')))}.toml")
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(CHEAP.format(name=_toml_string(name), methods=methods, outputs=outputs), encoding="utf-8")
    return p


@pytest.fixture
def no_work(monkeypatch):
    """The main job with its scenes' work replaced by a failure: a refusal must come before it."""

    def ran(*args, **kwargs):
        raise AssertionError("a scene ran before the refusal")

    monkeypatch.setattr(runner, "run_scene", ran)


#: Scene names that are (in any case) the name of a file the suite writes into the reports folder.
SUITE_NAMES = [
    "summary",
    "runs",
    "errata",
    "stability",
    "scaling",
    "paper_table",
    "error_vs_runtime",
    "SUMMARY",
    "Errata",
    "scaling-quick",
    "stability-quick",
    "stability-families",
    "benchmarks-full",
    "equations_size",
]


@pytest.mark.case("D2", "D3")
@pytest.mark.parametrize("name", SUITE_NAMES)
def test_a_scene_named_like_a_suite_report_is_refused_before_any_work(tmp_path, no_work, name):
    """A scene named like one of the suite's own reports (summary, runs, errata, stability,
    scaling, paper_table, their -quick and figure names, in any case) is refused before any work,
    in one line naming the scene file, its field 'name' and the report."""
    rep = tmp_path / "rep"
    with pytest.raises(ValueError, match=r"field 'name': .*the suite's own report") as e:
        main_job(rep, _scene(tmp_path, name))
    assert "\n" not in str(e.value) and repr(name) in str(e.value)
    assert not rep.exists() or not list(rep.iterdir())


@pytest.mark.case("D2", "D3")
def test_every_report_the_suite_writes_is_reserved(tmp_path, no_work):
    """Every file name the suite's writers take (bench/output/publish.py, where they take
    them from) is refused as a scene name, by its stem."""
    from exo_bench.bench.output.publish import suite_files

    names = suite_files()
    assert {"summary.md", "runs.json", "errata.md", "stability.md", "scaling.md", "paper_table-quick.md"} <= names
    for n in names:
        with pytest.raises(ValueError, match="the suite's own report"):
            main_job(tmp_path / "rep", _scene(tmp_path, Path(n).stem))


@pytest.mark.case("D3")
def test_a_scene_named_errata_leaves_the_errata_report_alone(tmp_path):
    """`exo-bench run` of a scene named errata exits 2 with one line and errata.md stays byte for byte."""
    from cli_runs import run_cli

    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "errata.md").write_text("# Errata\n\nthe suite's own report\n")
    rc, _, err = run_cli(["run", _scene(tmp_path, "errata"), "--reports", rep])
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "errata.md" in err, err
    assert (rep / "errata.md").read_text() == "# Errata\n\nthe suite's own report\n"
    assert sorted(p.name for p in rep.iterdir()) == ["errata.md"]


@pytest.mark.case("D4")
@pytest.mark.parametrize(
    "first,second",
    [
        ("x", "x"),  # one name twice (two files in two folders)
        ("A", "a"),  # file systems may fold case
        ("a b", "a_b"),  # one file name after encoding
        ("a.b", "a_b"),
        ("Fig 1", "fig_1"),
    ],
)
def test_two_scenes_with_one_file_name_in_one_run_are_refused(tmp_path, no_work, first, second):
    """Two scenes of one run whose names are one file name (equal, equal but for case, or equal
    after the file-name encoding) are refused before any work, in one
    line naming both scene files."""
    a = _scene(tmp_path / "one", first, outputs='["table", "equations"]')
    b = _scene(tmp_path / "two", second)
    with pytest.raises(ValueError, match="in this run") as e:
        main_job(tmp_path / "rep", a, b)
    assert str(a) in str(e.value) and str(b) in str(e.value) and "\n" not in str(e.value)


@pytest.mark.case("D4")
@pytest.mark.parametrize("name", ["equations-x", "Equations-exo5-3d", "x-quick", "fig2a-2d-QUICK"])
def test_a_scene_named_like_another_scenes_pages_is_refused(tmp_path, no_work, name):
    """A scene named like the equations page of another scene (equations-x.md is scene x's) or
    like a narrower run's page of another (x-quick.md) is refused before any work, in one line."""
    with pytest.raises(ValueError, match="field 'name': .*other scenes'") as e:
        main_job(tmp_path / "rep", _scene(tmp_path, name))
    assert "\n" not in str(e.value)


@pytest.mark.case("D4")
def test_one_scene_named_twice_on_the_command_line_is_refused(tmp_path, no_work):
    """A scene named twice in one run (one file, or a shipped name twice) is refused before any
    work, in one line saying so."""
    with pytest.raises(ValueError, match="named twice in this run"):
        main_job(tmp_path / "rep", _scene(tmp_path, "x", file="x.toml"), tmp_path / "x.toml")
    with pytest.raises(ValueError, match="exo5-2d.toml: named twice in this run"):
        runner.run_main_job(RunOptions(scenes=("exo5-2d", "exo5-2d"), reports=str(tmp_path / "rep")))


SPOOFING = [" ", "a\u202eb", "a\u0085b", "a\u2028b", "\u200bexo5-3d", "x\u2066y", "tab\tname", " lead", "trail "]


@pytest.mark.case("U9")
@pytest.mark.parametrize("name", SPOOFING)
def test_a_spoofing_scene_name_is_refused_at_load(tmp_path, name):
    """A scene name holding a space at its edge, a bidi override (U+202E), U+0085, U+2028 or
    another control, format or separator character is refused when the scene is loaded, naming the
    file, the field and the character."""
    p = _scene(tmp_path, name)
    with pytest.raises(ValueError, match=re.escape(f"{p}: field 'name': ")) as e:
        load_scene(p)
    assert "\n" not in str(e.value)


@pytest.mark.case("U9")
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.text(st.characters(exclude_categories=("Cs",)), min_size=1, max_size=12))
def test_a_scene_name_is_refused_or_becomes_a_safe_file_name(tmp_path_factory, name):
    """Any scene name is either refused at load (exactly when models/files.py refuses it, or it
    holds a path separator or starts with a dot) or every file the scene writes is named by the
    file-name encoder: ASCII letters, digits, '_' and '-', never a leading '-' or '.'."""
    from exo_bench.bench.studies.scene_run import scene_files

    d = tmp_path_factory.mktemp("names")
    p = _scene(d, name, outputs='["table", "moments", "recording", "equations"]')
    refused = name_problem(name) is not None or name.startswith(".") or any(c in "/\\" for c in name)
    if refused:
        with pytest.raises(ValueError, match="field 'name'"):
            load_scene(p)
        return
    files = scene_files(load_scene(p))
    assert len(files) == 5
    for f in files:
        assert re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_-]*\.(md|png|rrd|tex)", f), (name, f)


@pytest.mark.case("U10")
@pytest.mark.parametrize(
    "field,methods,outputs,duplicate",
    [
        ("methods", '["pinocchio", "recurrence", "pinocchio"]', '["table"]', "pinocchio"),
        ("outputs", '["pinocchio"]', '["table", "moments", "table"]', "table"),
    ],
)
def test_a_method_or_output_named_twice_is_refused_at_load(tmp_path, field, methods, outputs, duplicate):
    """A scene naming a method or an output twice is refused at load in one line naming the field
    and the duplicate (it produced duplicate rows)."""
    p = _scene(tmp_path, "dup", methods=methods, outputs=outputs)
    with pytest.raises(ValueError, match=re.escape(f"field '{field}'") + f".*{duplicate!r} twice") as e:
        load_scene(p)
    assert "\n" not in str(e.value)
