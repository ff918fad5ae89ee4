"""Nothing is written where a user did not name it (issue 38): a file ``-o`` whose folder is missing
is refused in one line (never made), and a sweep's checkpoints live inside the ``--reports`` folder."""

from __future__ import annotations

import pytest

from cli_runs import run_cli


def _tree(root) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.mark.parametrize(
    "argv",
    [
        ["urdf", "fig1-2d", "-o"],
        ["mjcf", "fig1-2d", "--no-check", "-o"],
        ["states", "fig1-2d", "-o"],
    ],
)
def test_a_file_output_in_a_missing_folder_is_refused_and_no_folder_is_made(argv, tmp_path):
    target = tmp_path / "nonexistent" / "dir" / "x.out"
    code, out, err = run_cli([*argv, target])
    assert code == 2, (out, err)
    assert len(err.strip().splitlines()) == 1 and "does not exist" in err and "nonexistent" in err, err
    assert _tree(tmp_path) == []


def test_a_file_output_under_a_file_is_refused_in_one_line(tmp_path):
    (tmp_path / "f").write_text("keep")
    code, _, err = run_cli(["urdf", "fig1-2d", "-o", tmp_path / "f" / "x.urdf"])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "cannot make its folder" in err, err
    assert (tmp_path / "f").read_text() == "keep"


def test_a_file_output_in_an_existing_folder_is_written(tmp_path):
    code, _, err = run_cli(["urdf", "fig1-2d", "-o", tmp_path / "x.urdf"])
    assert code == 0, err
    assert (tmp_path / "x.urdf").read_text().lstrip().startswith("<")


def test_bench_reports_keeps_its_checkpoints_inside_the_folder_named(tmp_path, monkeypatch):
    """``bench --reports X`` (the cluster sweep) wrote its checkpoints to ``X/../.exo-bench-sweep``: now
    inside X. The sweep's measuring and report drawing are stubbed; the stub checkpoints a row where the
    real sweep does (:func:`~exo_bench.bench.cluster.checkpoints.checkpoint_dir` of the folder given)."""
    from exo_bench.bench.cluster import commands
    from exo_bench.bench.cluster.checkpoints import checkpoint_dir
    from exo_bench.bench.cluster.cluster import SweepOutcome

    given = []

    def sweep(files, profile, checkpoints, **kw):
        given.append(checkpoints)
        folder = checkpoint_dir(checkpoints, "c0de")
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "row.json").write_text("{}")
        return SweepOutcome(merged={}, skips=[], rows=[])

    monkeypatch.setattr(commands, "run_sweep", sweep)
    monkeypatch.setattr(commands, "_write_reports", lambda *a, **k: [])
    parent = tmp_path / "parent"
    reports = parent / "X"
    reports.mkdir(parents=True)
    before = _tree(parent)
    code, out, err = run_cli(["bench", "--reports", reports, "--workers", "1"])
    assert code == 0, err
    assert given and given[0].resolve().is_relative_to(reports.resolve()), given
    outside = [p for p in _tree(parent) if not p.startswith("X")]
    assert outside == [p for p in before if not p.startswith("X")], outside
    assert (reports / ".exo-bench-sweep" / "c0de" / "row.json").is_file()


def test_stability_checkpoints_are_inside_the_reports_folder(tmp_path):
    from exo_bench.bench.cluster.checkpoints import default_checkpoints

    reports = tmp_path / "X"
    assert default_checkpoints(reports).resolve().parent == reports.resolve()
