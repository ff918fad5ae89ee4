"""Nothing is written where a user did not name it (issue 38): a file ``-o`` whose folder is missing
is refused in one line (never made), and a sweep's checkpoints live inside the ``--reports`` folder."""

from __future__ import annotations

import contextlib
import io

import pytest

from exo_bench.bench.cli import app as cli


def _run(*argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


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
    code, out, err = _run(*argv, target)
    assert code == 2, (out, err)
    assert len(err.strip().splitlines()) == 1 and "does not exist" in err and "nonexistent" in err, err
    assert _tree(tmp_path) == []


def test_a_file_output_under_a_file_is_refused_in_one_line(tmp_path):
    (tmp_path / "f").write_text("keep")
    code, _, err = _run("urdf", "fig1-2d", "-o", tmp_path / "f" / "x.urdf")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "cannot make its folder" in err, err
    assert (tmp_path / "f").read_text() == "keep"


def test_a_file_output_in_an_existing_folder_is_written(tmp_path):
    code, _, err = _run("urdf", "fig1-2d", "-o", tmp_path / "x.urdf")
    assert code == 0, err
    assert (tmp_path / "x.urdf").read_text().lstrip().startswith("<")
