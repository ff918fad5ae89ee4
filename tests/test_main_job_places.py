"""Where the main job (``exo-bench run``, the README's first command) writes, and what it prints
(issue 38: on a fresh clone it left 44 untracked files, wrote every scene to ``*-quick.*`` because the
committed reports had MuJoCo and Drake rows, and printed ~330 lines of raw benchmark tables).

* The default run measures the default install's methods only and publishes into the reports folder
  itself; ``--full`` (the whole sweep, the optional engines) publishes into its ``full/`` folder. A
  wider run has its own place, so "a narrower run never overwrites a wider one" never sends the
  default run to ``-quick`` names.
* The committed reports are the default run's own outputs: every file it writes is tracked, and
  ``reports/runs.json`` says one ``exo-bench run`` wrote them all (so after the main job on a fresh
  clone ``git status --porcelain`` has no ``??`` line and every report carries that run's id).
* The console shows one line per phase and a summary of what was written where; the raw output
  (what the suite's jobs and their subprocesses print) goes to ``main-job.log`` beside the reports.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from exo_bench.api.methods import METHODS
from exo_bench.bench.cli import run as run_cli
from exo_bench.bench.output.publish import (
    BENCHMARK_REPORTS,
    ERRATA,
    FULL_FOLDER,
    MAIN_JOB_LOG,
    MANIFEST,
    STABILITY_FIGURES,
    STABILITY_FORWARD_FIGURES,
    STABILITY_REPORT,
    SUMMARY,
    benchmark_json,
)
from exo_bench.bench.studies.options import RunOptions
from exo_bench.bench.studies.scene_run import scene_files
from exo_bench.bench.studies.scenes import load_scene, shipped_scene_names

REPO = Path(__file__).resolve().parents[1]
REPORTS = REPO / "reports"
#: What the suite's jobs print in the test below, as pytest-benchmark's tables would.
RAW = "RAW-BENCHMARK-TABLE-LINE"
RAW_SUBPROCESS = "RAW-SUBPROCESS-TABLE-LINE"


def default_run_files() -> set[str]:
    """Every file the default main job publishes into the reports folder (derivatives.png only where
    its report has rows: it has them in the quick sweep)."""
    scenes = [run_cli.default_install_scene(load_scene(n)) for n in shipped_scene_names()]
    return {
        SUMMARY,
        MANIFEST,
        MAIN_JOB_LOG,
        ERRATA,
        *BENCHMARK_REPORTS,
        benchmark_json("quick"),
        STABILITY_REPORT,
        *STABILITY_FIGURES,
        *STABILITY_FORWARD_FIGURES,
        *(f for sc in scenes for f in scene_files(sc)),
    }


def test_the_default_run_measures_the_default_install_only():
    """MuJoCo and Drake (extra [peers]) are measured by --full alone: the default run's reports are the
    same on every machine, with the engines installed or not."""
    extras = {m for m, s in METHODS.items() if s.extra}
    assert extras == {"mujoco", "drake"}
    for name in shipped_scene_names():
        sc = load_scene(name)
        assert extras & set(sc.methods), name  # the shipped scenes do list them
        default = run_cli.default_install_scene(sc)
        assert not extras & set(default.methods), name
        assert default.reference == sc.reference and default.reference in default.methods
        assert [m for m in sc.methods if m not in extras] == list(default.methods)


def test_a_full_run_has_its_own_folder(tmp_path):
    assert run_cli.main_job_folder(RunOptions(reports=tmp_path)) == tmp_path
    assert run_cli.main_job_folder(RunOptions(reports=tmp_path, full=True)) == tmp_path / FULL_FOLDER
    (tmp_path / FULL_FOLDER).symlink_to(tmp_path / "elsewhere")
    with pytest.raises(ValueError, match="link or a file"):
        run_cli.main_job_folder(RunOptions(reports=tmp_path, full=True))


def _tracked(folder: Path) -> set[str]:
    out = subprocess.run(
        ["git", "ls-files", "--", str(folder)], cwd=REPO, capture_output=True, text=True, check=True
    ).stdout
    return {Path(line).relative_to(folder.relative_to(REPO)).as_posix() for line in out.splitlines()}


def test_every_file_of_the_default_run_is_committed():
    """After the main job on a fresh clone, ``git status --porcelain`` has no ``??`` line: every file
    it writes is tracked (and none goes to a ``-quick`` name: no wider run's file is in the folder)."""
    if not (REPO / ".git").exists():
        pytest.skip("not a git checkout")
    tracked = _tracked(REPORTS)
    missing = sorted(default_run_files() - tracked)
    assert not missing, f"the main job writes these, not committed under reports/: {missing}"
    quick = [n for n in tracked if "/" not in n and "-quick." in n and n not in default_run_files()]
    assert not quick, f"a narrower run's file is committed: {quick}"


def test_the_committed_reports_are_one_default_run():
    """Every file the default run writes carries one run's id in reports/runs.json, that run's command is
    ``exo-bench run``, and every scene's summary rows are that run's (issue 38: summary.md named the new
    run in its header and listed the old run's rows)."""
    manifest = json.loads((REPORTS / MANIFEST).read_text())
    names = default_run_files() - {SUMMARY, MANIFEST}
    runs = {manifest["files"].get(n, {}).get("run") for n in names}
    assert len(runs) == 1 and None not in runs, sorted((n, manifest["files"].get(n, {}).get("run")) for n in names)
    (rid,) = runs
    assert manifest["runs"][rid]["command"] == "exo-bench run"
    assert {s["run"] for s in manifest["scenes"].values()} == {rid}
    for n in sorted(names):
        if n.endswith(".md"):
            assert rid in (REPORTS / n).read_text(), n  # the report carries the run's id itself


def _scene(tmp_path: Path) -> Path:
    p = tmp_path / "tiny.toml"
    p.write_text(
        'mechanism = "fig1-2d"\nmethods = ["pinocchio", "newton-euler", "mujoco"]\noutputs = ["table"]\n'
        '[motion]\nkind = "smooth-random"\nduration = 1.0\nsamples = 20\nseed = 0\n'
    )
    return p


def _job(staging: Path, out: Path, full: bool) -> int:
    print(RAW)
    subprocess.run([sys.executable, "-c", f"print({RAW_SUBPROCESS!r})"], check=True)  # inherits fd 1
    (staging / "job.md").write_text(f"# a job's report\n\nwritten into {staging}\n")
    return 0


@pytest.mark.parametrize("full", [False, True])
def test_the_console_shows_phases_and_where_the_raw_output_went(tmp_path, monkeypatch, capfd, full):
    """One scene and one suite job (stubbed: it prints raw tables itself and from a subprocess).
    The console has a line per phase and the summary naming the folder, summary.md and the log; the
    raw lines are in the log only. A --full run publishes into full/ and leaves the folder itself alone."""
    scene = _scene(tmp_path)
    monkeypatch.setattr(run_cli, "shipped_scene_names", lambda: [str(scene)])
    monkeypatch.setattr(run_cli, "_suite_jobs", lambda: [("the job (stub)", _job)])
    reports = tmp_path / "reports"
    rc = run_cli.run_main_job(RunOptions(reports=reports, full=full))
    console = capfd.readouterr().out
    assert rc == 0, console
    place = reports / FULL_FOLDER if full else reports
    assert RAW not in console and RAW_SUBPROCESS not in console, console
    log = (place / MAIN_JOB_LOG).read_text()
    assert RAW in log and RAW_SUBPROCESS in log, log
    assert "[1/2] scene tiny: done" in console and "[2/2] the job (stub): done" in console, console
    assert f"into {place}" in console and str(place / SUMMARY) in console and str(place / MAIN_JOB_LOG) in console
    assert len(console.splitlines()) < 30, console
    assert sorted(p.name for p in place.iterdir() if not p.name.startswith(".")) == sorted(
        [MAIN_JOB_LOG, MANIFEST, SUMMARY, "job.md", "tiny.md"]
    )
    if full:
        assert sorted(p.name for p in reports.iterdir() if not p.name.startswith(".")) == [FULL_FOLDER]
    table = (place / "tiny.md").read_text()
    assert ("| mujoco |" in table) is full  # the default run does not list the extra's method at all
