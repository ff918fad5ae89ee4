"""One lock per reports folder: concurrent runs publish one after the other and lose nothing."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from cli_runs import EXO_BENCH

#: The cheapest scene: a two-link planar preset, one method (Pinocchio, no compilation), 8 samples,
#: the table only (about a second per process, most of it imports).
CHEAP = """name = "{name}"
mechanism = "fig1-2d"
methods = ["pinocchio"]
outputs = ["table"]
[motion]
kind = "smooth-random"
duration = 1.0
samples = 8
"""


def _cheap_scene(d: Path, name: str) -> Path:
    p = d / f"{name}.toml"
    p.write_text(CHEAP.format(name=name))
    return p


def _assert_nothing_lost(rep: Path, names: list[str]) -> None:
    """Every scene of every run has its rows in runs.json and summary.md, and its page exists and
    is listed as a report file."""
    manifest = json.loads((rep / "runs.json").read_text())
    summary = (rep / "summary.md").read_text()
    lost = [n for n in names if n not in manifest["scenes"]]
    assert not lost, f"scenes lost from runs.json: {lost}"
    lost = [n for n in names if f"| {n} | pinocchio |" not in summary]
    assert not lost, f"scenes lost from summary.md: {lost}"
    lost = [n for n in names if not (rep / f"{n}.md").is_file()]
    assert not lost, f"scene pages missing: {lost}"
    lost = [n for n in names if f"{n}.md" not in manifest["files"] or f"| {n}.md | `" not in summary]
    assert not lost, f"files not listed in runs.json and summary.md: {lost}"
    for n in names:  # each row and file is marked by the run that made it, and that run is listed
        run = manifest["scenes"][n]["run"]
        assert manifest["files"][f"{n}.md"]["run"] == run and manifest["runs"][run]["status"] == "complete"
    assert not list(rep.glob(".staging-*"))


def _start_run(scene: Path, rep: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [*EXO_BENCH, "run", str(scene), "--reports", str(rep)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.case("D1")
def test_four_concurrent_runs_into_one_folder_lose_nothing(tmp_path):
    """Four `exo-bench run`s started at once into one reports folder each publish in turn, and
    summary.md and runs.json hold every scene and file of every run. End to end: four real
    processes of the CLI, each running one cheap scene, started together, twice into one folder
    (the ten repetitions are those of the publication step, in
    test_four_concurrent_publications_repeated_lose_nothing, which is what the lock serialises)."""
    rep = tmp_path / "rep"
    names: list[str] = []
    for rnd in range(2):
        batch = [f"r{rnd}-p{k}" for k in range(4)]
        procs = [_start_run(_cheap_scene(tmp_path, n), rep) for n in batch]
        for p in procs:
            out, err = p.communicate(timeout=1800)
            assert p.returncode == 0, err
        names += batch
        _assert_nothing_lost(rep, names)


#: One run's publication step, as the main job does it (bench/cli/run.py): its staged scene page and
#: its summary rows are published into the folder once every publisher has staged (the file GO exists).
PUBLISHER = """
import sys, time
from pathlib import Path
from exo_bench.models.files import atomic_write
from exo_bench.bench.output.publish import publish_run, staging_dir

rep, name, go = Path(sys.argv[1]), sys.argv[2], Path(sys.argv[3])
with staging_dir(rep) as st:
    atomic_write(st / f"{name}.md", f"# Scene {name}\\n")
    print("staged", flush=True)
    while not go.exists():
        time.sleep(0.005)
    rows = {name: [[name, "pinocchio", "0.0e+00 (vs pinocchio)", "1.00", ""]]}
    publish_run(st, rep, rows, f"exo-bench run {name}")
"""


@pytest.mark.case("D1")
def test_four_concurrent_publications_repeated_lose_nothing(tmp_path):
    """Four runs publishing into one folder at the same moment, ten times over, lose no scene, row
    or file: each publisher waits for the folder's lock, re-reads runs.json under it and merges its
    own rows. Four real processes per repetition, released together once all four have staged
    their files (the publication step of the main job; the end-to-end runs are in
    test_four_concurrent_runs_into_one_folder_lose_nothing)."""
    rep = tmp_path / "rep"
    names: list[str] = []
    for rnd in range(10):
        go = tmp_path / f"go-{rnd}"
        batch = [f"r{rnd}-p{k}" for k in range(4)]
        procs = [
            subprocess.Popen(
                [sys.executable, "-c", PUBLISHER, str(rep), n, str(go)],
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
            )
            for n in batch
        ]
        for p in procs:  # every publisher has staged its page before any publishes
            assert p.stdout is not None and p.stdout.readline() == "staged\n", p.communicate(timeout=60)[1]
        go.touch()
        for p in procs:
            _, err = p.communicate(timeout=1800)
            assert p.returncode == 0, err
        names += batch
        _assert_nothing_lost(rep, names)


def _publish_one(rep: Path, name: str) -> list[Path]:
    """One run's publication of one scene page (a run of its own: a new run identifier)."""
    from exo_bench.bench.output.provenance import new_run_id, set_run_id
    from exo_bench.models.files import atomic_write
    from exo_bench.bench.output.publish import publish_run, staging_dir

    with staging_dir(rep) as st:
        atomic_write(st / f"{name}.md", f"# Scene {name}\n")
        set_run_id(new_run_id())
        rows = {name: [[name, "pinocchio", "0.0e+00 (vs pinocchio)", "1.00", ""]]}
        return publish_run(st, rep, rows, f"exo-bench run {name}")


class _GiveUp(Exception):
    """Raised by an injected pause: the test stops a waiting run instead of letting it wait on."""


@pytest.mark.case("D1")
def test_a_publisher_blocked_by_the_lock_proceeds_after_release_and_merges(tmp_path, monkeypatch):
    """A run that finds the reports folder's lock held waits, publishing nothing; once the lock is
    released it re-reads runs.json and merges its rows into what the holder published meanwhile.
    Deterministic: the test holds the lock itself and knows the publisher is waiting when it
    pauses between tries (an injected pause), not by timing."""
    import functools
    import threading
    import time

    from exo_bench.bench.output import publish as publishing
    from exo_bench.models.files import atomic_write
    from exo_bench.bench.output.publish import reports_lock

    rep = tmp_path / "rep"
    _publish_one(rep, "a")
    waiting = threading.Event()

    def pause(seconds: float) -> None:
        waiting.set()
        time.sleep(seconds)

    monkeypatch.setattr(publishing, "reports_lock", functools.partial(reports_lock, pause=pause))
    done: list[list[Path]] = []
    with reports_lock(rep, "the test, publishing scene c"):
        t = threading.Thread(target=lambda: done.append(_publish_one(rep, "b")))
        t.start()
        assert waiting.wait(timeout=1800), "the publisher never waited for the held lock"
        assert t.is_alive() and not done
        assert "b" not in json.loads((rep / "runs.json").read_text())["scenes"] and not (rep / "b.md").exists()
        # meanwhile the holder publishes its scene c, as a run holding the lock does
        manifest = publishing.read_manifest(rep)
        manifest["runs"]["20260101T000000Z-cccc"] = {"command": "exo-bench run c", "status": "complete"}
        manifest["scenes"]["c"] = {"run": "20260101T000000Z-cccc", "rows": [["c", "pinocchio", "x", "1.00", ""]]}
        atomic_write(rep / "runs.json", json.dumps(manifest))
    t.join(timeout=1800)
    assert not t.is_alive() and done
    manifest = json.loads((rep / "runs.json").read_text())
    assert {"a", "b", "c"} <= set(manifest["scenes"])
    summary = (rep / "summary.md").read_text()
    assert all(f"| {n} | pinocchio |" in summary for n in "abc")
    assert (rep / "a.md").is_file() and (rep / "b.md").is_file()


@pytest.mark.case("D1")
def test_the_lock_of_a_killed_holder_is_free_at_once(tmp_path):
    """A run killed (SIGKILL) while holding the reports folder's lock does not make the next run
    wait: the kernel releases the lock with the process. While it lives, the lock is taken."""
    from exo_bench.bench.output.publish import reports_lock

    rep = tmp_path / "rep"
    rep.mkdir()
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, time\nfrom exo_bench.bench.output.publish import reports_lock\n"
            f"with reports_lock({str(rep)!r}, 'a run killed while publishing'):\n"
            "    print('held', flush=True)\n    time.sleep(600)\n",
        ],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"

        def give_up(seconds: float) -> None:
            raise _GiveUp

        with pytest.raises(_GiveUp):  # held: the first try fails and the run would wait
            with reports_lock(rep, pause=give_up, say=lambda line: None):
                pass
    finally:
        holder.kill()
        holder.wait(timeout=60)
    with reports_lock(rep, pause=give_up):  # free at the first try: no pause
        pass


def test_a_waiting_run_says_so_once_naming_the_holder(tmp_path):
    """A run waiting for the lock says so in one line once it has waited notice_after seconds (an
    injected clock: one second per try), naming the holder's process and command."""
    import os

    from exo_bench.bench.output.publish import reports_lock

    rep = tmp_path / "rep"
    rep.mkdir()
    now = [0.0]
    said: list[tuple[float, str]] = []

    def pause(seconds: float) -> None:
        now[0] += 1.0
        if now[0] > 10:
            raise _GiveUp

    with reports_lock(rep, "exo-bench run a"):
        with pytest.raises(_GiveUp):
            with reports_lock(
                rep, notice_after=3.0, clock=lambda: now[0], pause=pause, say=lambda s: said.append((now[0], s))
            ):
                pass
    assert [t for t, _ in said] == [3.0]
    line = said[0][1]
    assert f"process {os.getpid()}" in line and "(exo-bench run a)" in line and ".exo-bench.lock" in line
    assert "\n" not in line


@pytest.mark.parametrize("kind", ["symlink", "fifo", "folder"])
def test_a_planted_lock_file_is_refused_in_one_line_before_any_work(tmp_path, monkeypatch, kind):
    """A symlink, FIFO or folder planted at the reports folder's lock file is refused in one line
    naming it (exit 2 from the CLI) before any scene runs; a link's target is left as it was."""
    import os

    import exo_bench.bench.cli.run as runner
    from exo_bench.bench.studies.options import RunOptions
    from cli_runs import run_cli

    rep = tmp_path / "rep"
    rep.mkdir()
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    lock = rep / ".exo-bench.lock"
    {"symlink": lambda: lock.symlink_to(victim), "fifo": lambda: os.mkfifo(lock), "folder": lock.mkdir}[kind]()
    scene = _cheap_scene(tmp_path, "a")
    rc, out, err = run_cli(["run", scene, "--reports", rep])
    assert rc == 2 and len(err.strip().splitlines()) == 1 and ".exo-bench.lock" in err, err
    assert victim.read_text() == "precious\n" and sorted(p.name for p in rep.iterdir()) == [".exo-bench.lock"]

    def no_work(*args, **kwargs):
        raise AssertionError("a scene ran")

    monkeypatch.setattr(runner, "run_scene", no_work)
    with pytest.raises(ValueError, match="exo-bench.lock: is (a symlink|a FIFO|a folder)"):
        runner.run_main_job(RunOptions(scenes=(str(scene),), reports=str(rep)))
