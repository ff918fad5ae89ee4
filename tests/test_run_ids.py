"""Runs never overwrite results of a wider run, and every report file says which run made it.

Issue 16: ``exo-bench run fig2a-2d`` overwrote summary.md with that scene alone (26 rows became
6), and an interrupted run left old and new reports side by side with nothing saying which is which.
"""

import json
import re
import shutil
from pathlib import Path

import pytest
from cli_runs import main_job

import exo_bench.bench.output.publish as publishing
from exo_bench.bench.output.provenance import run_id_of
from exo_bench.models.mechanism.presets import random_tree

ROOT = Path(__file__).resolve().parent.parent

SCENE = """
name = "{name}"
mechanism = "tree.json"
methods = ["pinocchio", "matrix-factored"]
outputs = {outputs}
[motion]
kind = "smooth-random"
samples = 30
"""


def _scene(tmp_path, name, outputs='["table"]'):
    (tmp_path / "tree.json").write_text(random_tree(3, 2, 5).to_json())
    p = tmp_path / f"{name}.toml"
    p.write_text(SCENE.format(name=name, outputs=outputs))
    return p


def _rows(summary: str) -> dict[str, list[str]]:
    """scene -> the run of each of its rows in the summary table."""
    out: dict[str, list[str]] = {}
    for line in summary.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(cells) == 6 and cells[0] not in ("scene",) and not cells[0].startswith("-"):
            out.setdefault(cells[0], []).append(cells[5].strip("`"))
    return out


def _runs(rep) -> dict:
    return json.loads((rep / "runs.json").read_text())


def test_running_one_scene_keeps_every_other_scenes_rows(tmp_path):
    a, b = _scene(tmp_path, "a"), _scene(tmp_path, "b")
    rep = tmp_path / "rep"
    assert main_job(rep, a, b) == 0
    first = _runs(rep)["files"]["a.md"]["run"]
    assert main_job(rep, b) == 0
    second = _runs(rep)["files"]["b.md"]["run"]
    assert first != second
    rows = _rows((rep / "summary.md").read_text())
    assert rows == {"a": [first, first], "b": [second, second]}
    text = (rep / "summary.md").read_text()
    assert f"| a.md | `{first}` |" in text and f"| b.md | `{second}` |" in text


def test_a_folder_from_before_run_identifiers_keeps_its_rows(tmp_path):
    """The shipped reports/summary.md (26 rows, no run identifiers): running one scene named like a
    shipped one replaces that scene's rows only."""
    rep = tmp_path / "rep"
    rep.mkdir()
    old = (ROOT / "reports" / "summary.md").read_text()
    if "| run |" in old:
        pytest.skip("the checkout's reports already carry run identifiers")
    (rep / "summary.md").write_text(old)
    before = {k: len(v) for k, v in _old_rows(old).items()}
    assert sum(before.values()) == 25 and before["fig2a-2d"] == 5  # the "26 rows": 25 and the header
    assert main_job(rep, _scene(tmp_path, "fig2a-2d")) == 0
    after = _rows((rep / "summary.md").read_text())
    assert {k: len(v) for k, v in after.items()} == {**before, "fig2a-2d": 2}
    assert all(r == "unknown (before run identifiers)" for k, v in after.items() if k != "fig2a-2d" for r in v)


def _old_rows(text):
    out = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("| ") and len(cells) == 5 and cells[0] != "scene" and not cells[0].startswith("-"):
            out.setdefault(cells[0], []).append(cells)
    return out


def test_every_report_carries_its_run(tmp_path):
    rep = tmp_path / "rep"
    assert main_job(rep, _scene(tmp_path, "a", '["table", "moments"]')) == 0
    run = _runs(rep)["files"]["a.md"]["run"]
    assert re.fullmatch(r"[0-9]{8}T[0-9]{6}Z-[0-9a-f]{4}", run)
    assert run_id_of(rep / "a.md") == run and run_id_of(rep / "a-moments.png") == run
    assert run_id_of(rep / "summary.md") == run
    assert set(_runs(rep)["files"]) == {"a.md", "a-moments.png"}


class _Killed(BaseException):
    """Stands for SIGKILL in the middle of publishing (signals are held then; only a kill gets in)."""


def test_a_run_killed_while_publishing_is_announced_and_each_file_marked(tmp_path, monkeypatch):
    a = _scene(tmp_path, "a", '["table", "moments"]')
    rep = tmp_path / "rep"
    assert main_job(rep, a) == 0
    old = _runs(rep)["files"]["a.md"]["run"]
    real = publishing.publish

    def die_after_one(files, out):
        real(files[:1], out)
        raise _Killed

    monkeypatch.setattr(publishing, "publish", die_after_one)
    with pytest.raises(_Killed):
        main_job(rep, a)
    manifest = _runs(rep)
    new = next(r for r, v in manifest["runs"].items() if v["status"] == "publishing")
    text = (rep / "summary.md").read_text()
    assert f"Run `{new}`" in text and "was interrupted while its files were being published" in text
    # each file in the folder is marked by the run that wrote it: its own provenance agrees with the summary
    files = sorted(
        p.name for p in rep.iterdir() if not p.name.startswith(".") and p.name not in ("summary.md", "runs.json")
    )
    assert files == ["a-moments.png", "a.md"]
    marks = {f: run_id_of(rep / f) for f in files}
    assert sorted(marks.values()) == sorted([old, new])  # one file from each run
    for f in files:  # the summary names both possible runs of each file; the file's own mark says which
        assert (
            f"| {f} | `{new}` if published before the interruption, else `{old}` (the file's own mark says which)"
            in text
        ), f
    # the next whole run completes the folder and no longer announces an interruption of files it replaced
    monkeypatch.setattr(publishing, "publish", real)
    assert main_job(rep, a) == 0
    text = (rep / "summary.md").read_text()
    assert "was interrupted" not in text
    assert len({run_id_of(rep / f) for f in files}) == 1


def test_a_standalone_report_command_is_recorded(tmp_path, monkeypatch):
    """exo-bench errata on its own: its file is marked with its run in runs.json and summary.md, and
    the scenes' rows stay."""
    from cli_runs import run_cli

    rep = tmp_path / "rep"
    assert main_job(rep, _scene(tmp_path, "a")) == 0

    def fake_errata(args):
        from exo_bench.bench.output.provenance import provenance
        from exo_bench.models.files import atomic_write

        atomic_write(Path(args.reports) / "errata.md", "# Errata\n\n" + provenance("exo-bench errata"))
        return 0

    monkeypatch.setattr("exo_bench.bench.studies.errata.run", fake_errata)
    rc, _, err = run_cli(["errata", "--reports", rep])
    assert rc == 0, err
    manifest = _runs(rep)
    assert manifest["files"]["errata.md"]["run"] == run_id_of(rep / "errata.md")
    assert _rows((rep / "summary.md").read_text())["a"]
    shutil.rmtree(rep)


def test_the_run_of_a_png_is_read_back_exactly(tmp_path):
    """The identifier sits in a PNG text chunk followed by binary bytes (the chunk's CRC), which
    can look like more hex digits: 32 identifiers read back exactly."""
    from matplotlib.figure import Figure

    from exo_bench.bench.output import provenance as reporting

    keep = reporting.current_run_id()
    try:
        for k in range(32):
            rid = reporting.set_run_id(reporting.new_run_id())
            fig = Figure(figsize=(1, 1))
            fig.add_subplot().plot([0, k])
            reporting.save_figure(fig, tmp_path / "f.png", dpi=20)
            assert run_id_of(tmp_path / "f.png") == rid
    finally:
        reporting.set_run_id(keep)


def test_a_run_without_an_engine_goes_beside_the_reports_that_measured_it(tmp_path, monkeypatch, capsys):
    """The README's first command installs no extra ``[peers]``: its run of a scene whose published
    report measured MuJoCo and Drake must not replace that report with "not installed" rows. Here
    matrix-factored stands for the engine: the second run cannot prepare it (MissingExtra, as a
    missing engine raises), so the scene's files go beside as ``-quick`` and its summary rows stay
    the first run's; once the engine is back, the scene's report is replaced as before. A scene
    whose published rows never measured the method is replaced too."""
    import exo_bench.bench.studies.study as study
    from exo_bench.models.runtime.prepared import MissingExtra

    a = _scene(tmp_path, "a", outputs='["table", "overview"]')
    rep = tmp_path / "rep"
    assert main_job(rep, a) == 0
    first = _runs(rep)["files"]["a.md"]["run"]
    table = (rep / "a.md").read_text()
    real = study.prepare

    def no_engine(mech, method, **kw):
        if method == "matrix-factored":
            raise MissingExtra("matrix-factored: its engine is not installed (test)")
        return real(mech, method, **kw)

    monkeypatch.setattr(study, "prepare", no_engine)
    capsys.readouterr()
    assert main_job(rep, a) == 0
    out = capsys.readouterr().out
    assert "have rows of matrix-factored, not installed here" in out and "a-quick.md" in out
    assert (rep / "a.md").read_text() == table  # the wider report, untouched
    assert "skipped: matrix-factored: its engine is not installed" in (rep / "a-quick.md").read_text()
    assert (rep / "a-overview-quick.png").is_file()
    runs = _runs(rep)
    second = runs["files"]["a-quick.md"]["run"]
    assert second != first and runs["files"]["a.md"]["run"] == first
    assert _rows((rep / "summary.md").read_text()) == {"a": [first, first]}

    b = _scene(tmp_path, "b")  # never measured with the engine: nothing wider to keep
    assert main_job(rep, b) == 0 and not (rep / "b-quick.md").exists()
    monkeypatch.setattr(study, "prepare", real)
    assert main_job(rep, a) == 0
    third = _runs(rep)["files"]["a.md"]["run"]
    assert third not in (first, second) and _rows((rep / "summary.md").read_text())["a"] == [third, third]
