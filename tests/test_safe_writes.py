"""Issue 34, S4, D6, D7, U4, U5, U11: what the suite's writes may replace, and how.

Every file the command line writes goes through one writer (bench/output/files.py): it never
follows a symlink at the file it replaces (a link planted in an output folder is refused in one line
naming it), keeps a replaced file's mode, refuses to overwrite the command's own input, treats the
process's stdout as a stream, names the file in every write error, and a reader that goes away (a
broken pipe) never ends in exit 0.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
from pathlib import Path

import pytest
from cli_runs import EXO_BENCH, cli_process, run_cli

from exo_bench.models.mechanism.presets import fig1

EXO = EXO_BENCH


def _mech_file(d: Path, name: str = "m.json", mech_name: str | None = None) -> Path:
    data = fig1(2).to_dict()
    if mech_name is not None:
        data["name"] = mech_name
    (d / name).write_text(json.dumps(data))
    return d / name


#: Every command that writes one file (``-o FILE``): argv for an output path, and the file it writes.
ONE_FILE = {
    "urdf": lambda o: ["urdf", "fig1-2d", "-o", o],
    "mjcf": lambda o: ["mjcf", "fig1-2d", "--no-check", "-o", o],
}
#: Every command that writes into a folder (``-o DIR``), and a file it writes there.
FOLDER = {
    "equations-c": (lambda o: ["equations", "fig1-2d", "--format", "c", "-o", o], "fig1_2d.c"),
    "equations-python": (lambda o: ["equations", "fig1-2d", "--format", "python", "-o", o], "fig1_2d.py"),
    "equations-latex": (lambda o: ["equations", "fig1-2d", "--format", "latex", "-o", o], "equations-fig1-2d.tex"),
}


def _plant(kind: str, link: Path, tmp: Path) -> Path | None:
    """A symlink at ``link`` of ``kind``; returns the victim file it points to (or None)."""
    other = tmp / "elsewhere"
    other.mkdir(exist_ok=True)
    if kind == "file-same-folder":
        victim = link.parent / "victim.txt"
    elif kind == "file-other-folder":
        victim = other / "victim.txt"
    elif kind == "folder":
        os.symlink(other, link)
        return None
    else:  # dangling: a write through it would create the file it names
        os.symlink(other / "created-by-the-write", link)
        return None
    victim.write_text("precious\n")
    os.symlink(victim, link)
    return victim


LINKS = ["file-same-folder", "file-other-folder", "folder", "dangling"]


def _assert_refused_link(rc: int, err: str, link: Path, victim: Path | None, tmp: Path) -> None:
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert "symlink" in err and str(link) in err, err
    assert link.is_symlink()
    if victim is not None:
        assert victim.read_text() == "precious\n"
    assert not (tmp / "elsewhere" / "created-by-the-write").exists()
    assert not (tmp / "elsewhere" / link.name).exists()


@pytest.mark.case("S4")
@pytest.mark.parametrize("kind", LINKS)
@pytest.mark.parametrize("command", sorted(FOLDER))
def test_a_link_planted_in_an_output_folder_is_refused_naming_it(tmp_path, command, kind):
    """A symlink planted in an output folder where a file goes is refused in one line naming it
    (exit 2); the file it points to is untouched. Every folder command, links to a file in the
    folder, to one in another folder, to a folder, and dangling."""
    argv, name = FOLDER[command]
    out = tmp_path / "out"
    out.mkdir()
    victim = _plant(kind, out / name, tmp_path)
    rc, _, err = run_cli(argv(out))
    _assert_refused_link(rc, err, out / name, victim, tmp_path)


@pytest.mark.case("S4")
@pytest.mark.parametrize("kind", LINKS)
@pytest.mark.parametrize("command", sorted(ONE_FILE))
def test_a_link_named_as_the_output_file_is_refused_naming_it(tmp_path, command, kind):
    """``-o LINK`` is refused in one line naming the link (exit 2), whatever it points to; the file
    it points to is untouched."""
    link = tmp_path / "out.xml"
    victim = _plant(kind, link, tmp_path)
    rc, _, err = run_cli(ONE_FILE[command](link))
    _assert_refused_link(rc, err, link, victim, tmp_path)


@pytest.mark.case("S4")
def test_a_link_planted_among_the_reports_is_refused_before_publishing(tmp_path):
    """A symlink planted in a reports folder at a report's name is refused by the publisher in one
    line naming it; the file it points to is untouched."""
    from exo_bench.bench.output.publish import publish

    out, st = tmp_path / "rep", tmp_path / "st"
    out.mkdir()
    st.mkdir()
    (st / "summary.md").write_text("new\n")
    victim = _plant("file-other-folder", out / "summary.md", tmp_path)
    with pytest.raises(ValueError, match="summary.md.*symlink"):
        publish([st / "summary.md"], out)
    assert victim is not None and victim.read_text() == "precious\n"


def _staged(p: Path) -> Path:
    p.write_text("new\n")
    return p


@pytest.mark.case("S4")
@pytest.mark.parametrize("mode", [0o600, 0o640, 0o604])
def test_a_replaced_file_keeps_its_mode(tmp_path, mode):
    """A file the suite replaces keeps its mode (0600 stays 0600), by every writer: ``-o``, the
    atomic writer, the publisher."""
    from exo_bench.models.files import atomic_write
    from exo_bench.bench.output.publish import publish

    for i, write in enumerate(
        (
            lambda p: run_cli(["urdf", "fig1-2d", "-o", p])[0] == 0,
            lambda p: atomic_write(p, "new\n"),
            lambda p: publish([_staged(p.parent.parent / "st" / p.name)], p.parent),
        )
    ):
        d = tmp_path / str(i)
        (d / "out").mkdir(parents=True)
        (d / "st").mkdir()
        p = d / "out" / "f.urdf"
        p.write_text("old\n")
        os.chmod(p, mode)
        assert write(p)
        assert p.read_text() != "old\n"
        assert (p.stat().st_mode & 0o777) == mode, (i, oct(p.stat().st_mode))


@pytest.mark.case("S4")
def test_the_atomic_writers_refuse_a_link_in_the_api(tmp_path):
    """``atomic_write`` and ``atomic_path`` refuse a symlink at the file they replace (ValueError
    naming it), as the command line does."""
    from exo_bench.models.files import atomic_path, atomic_write

    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    os.symlink(victim, tmp_path / "report.md")
    with pytest.raises(ValueError, match="report.md.*symlink"):
        atomic_write(tmp_path / "report.md", "x")
    with pytest.raises(ValueError, match="report.md.*symlink"):
        with atomic_path(tmp_path / "report.md") as tmp:
            tmp.write_text("x")
    assert victim.read_text() == "precious\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.md", "victim.txt"]  # no temporary left


# ------------------------------------------------------------------------------ stdout is a stream
@pytest.mark.case("D6")
@pytest.mark.parametrize("command", sorted(ONE_FILE))
def test_o_dev_stdout_appends_to_a_log_and_never_replaces_it(tmp_path, command):
    """``-o /dev/stdout >> app.log`` appends to app.log (the same file, the same inode), as a
    stream: it is never replaced by a new file."""
    log = tmp_path / "app.log"
    log.write_text("earlier lines\n")
    ino = log.stat().st_ino
    with open(log, "a") as f:
        p = subprocess.run([*EXO, *ONE_FILE[command]("/dev/stdout")], stdout=f, stderr=subprocess.PIPE, timeout=1800)
    assert p.returncode == 0, p.stderr
    text = log.read_text()
    assert text.startswith("earlier lines\n<?xml") or text.startswith("earlier lines\n<"), text[:200]
    assert log.stat().st_ino == ino


@pytest.mark.case("U11")
@pytest.mark.parametrize("command", sorted(ONE_FILE))
def test_o_dash_is_stdout_and_creates_no_file(tmp_path, command):
    """``-o -`` writes stdout (no file named ``-``), as does ``-o /dev/stdout`` into a pipe."""
    p = cli_process(*ONE_FILE[command]("-"), timeout=1800, cwd=tmp_path)
    assert p.returncode == 0 and p.stdout.startswith("<"), p.stderr
    assert not (tmp_path / "-").exists()
    q = cli_process(*ONE_FILE[command]("/dev/stdout"), timeout=1800, cwd=tmp_path)
    assert q.returncode == 0 and q.stdout == p.stdout, q.stderr


@pytest.mark.case("U11")
@pytest.mark.parametrize("command", sorted(ONE_FILE))
def test_an_empty_output_or_a_folder_path_is_refused_for_a_one_file_command(tmp_path, command):
    """``-o ''`` is refused in one line (not stdout), and ``-o newdir/`` (a trailing slash: a
    folder) is refused for a command that writes one file, naming it; nothing is created."""
    rc, out, err = run_cli(ONE_FILE[command](""))
    assert rc == 2 and out == "" and "empty" in err and len(err.strip().splitlines()) == 1, (out, err)
    rc, out, err = run_cli(ONE_FILE[command](f"{tmp_path}/newdir/"))
    assert rc == 2 and "newdir/" in err and "folder" in err and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.case("U11")
def test_a_trailing_slash_is_a_folder_for_a_folder_command_and_dash_is_refused(tmp_path, monkeypatch):
    """``equations -o newdir/`` makes the folder; ``-o -`` (stdout) is refused by a command that
    writes several files, in one line."""
    rc, out, err = run_cli(["equations", "fig1-2d", "--format", "c", "-o", f"{tmp_path}/newdir/"])
    assert rc == 0 and (tmp_path / "newdir" / "fig1_2d.c").is_file(), err
    monkeypatch.chdir(tmp_path)  # a folder named "-" would be made here
    rc, out, err = run_cli(["equations", "fig1-2d", "--format", "c", "-o", "-"])
    assert rc == 2 and "stdout" in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "-").exists()


# ------------------------------------------------------------------------------ never over the input
@pytest.mark.case("D7")
@pytest.mark.parametrize("spelling", ["same", "dot-slash", "hard-link"])
@pytest.mark.parametrize("command", sorted(ONE_FILE))
def test_a_command_never_overwrites_its_own_input(tmp_path, command, spelling):
    """``urdf m.json -o m.json`` is refused in one line naming both (exit 2), however the output
    names the input (the same path, another spelling, a hard link); the input is unchanged."""
    m = _mech_file(tmp_path)
    before = m.read_bytes()
    out = {"same": m, "dot-slash": Path(f"{tmp_path}/./m.json"), "hard-link": tmp_path / "h.json"}[spelling]
    if spelling == "hard-link":
        os.link(m, out)
    argv = ONE_FILE[command](out)
    argv[1] = str(m)
    rc, _, err = run_cli(argv)
    assert rc == 2 and "its own input" in err and len(err.strip().splitlines()) == 1, err
    assert m.read_bytes() == before


@pytest.mark.case("D7")
def test_equations_never_overwrite_their_own_input(tmp_path):
    """A mechanism file ``m.py`` in the output folder that ``--format python`` would write as
    ``m.py`` is refused, naming it; the input is unchanged."""
    m = _mech_file(tmp_path, "m.py", mech_name="m")
    before = m.read_bytes()
    rc, _, err = run_cli(["equations", m, "--format", "python", "-o", tmp_path])
    assert rc == 2 and "its own input" in err and "m.py" in err, err
    assert m.read_bytes() == before


# ------------------------------------------------------------------------------ write errors name the file
def _small_files():
    """In the child: files of at most 64 bytes (EFBIG past them), SIGXFSZ ignored."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (64, 64))


@pytest.mark.case("U4")
@pytest.mark.parametrize("command", sorted(ONE_FILE) + ["equations-c"])
def test_a_write_error_names_the_file(tmp_path, command):
    """A write that fails (the disk full, a file size limit) is one line naming the file it was
    writing (exit 2), and leaves no file and no temporary behind."""
    if command in ONE_FILE:
        argv, target = ONE_FILE[command](tmp_path / "out.xml"), tmp_path / "out.xml"
    else:
        argv, target = FOLDER[command][0](tmp_path), tmp_path / FOLDER[command][1]
    p = cli_process(*argv, timeout=1800, preexec_fn=_small_files)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "File too large" in lines[0], p.stderr
    assert str(target.parent) in lines[0] and "internal error" not in lines[0], p.stderr
    assert [f for f in tmp_path.iterdir() if f.name.startswith(".")] == []


@pytest.mark.case("U4")
@pytest.mark.parametrize("command", ["presets", "urdf", "inverse"])
def test_a_full_stdout_is_named(tmp_path, command):
    """Output to a full device (``> /dev/full``) is one line naming stdout (exit 2), not a bare
    "No space left on device"."""
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    argv = {
        "presets": ["presets"],
        "urdf": ["urdf", "fig1-2d"],
        "inverse": ["inverse", "fig1-2d", _states_file(tmp_path), "--method", "matrix-factored"],
    }[command]
    with open("/dev/full", "w") as full:
        p = subprocess.run([*EXO, *map(str, argv)], stdout=full, stderr=subprocess.PIPE, text=True, timeout=1800)
    assert p.returncode == 2 and p.stderr == "exo-bench: error: stdout: No space left on device\n", p.stderr


# ------------------------------------------------------------------------------ a reader that goes away
def _states_file(d: Path) -> Path:
    from exo_bench.models.gait.motion import random_states

    q, qd, qdd = random_states(fig1(2), 3, 0)
    (d / "s.json").write_text(
        json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist(), "tau": qdd.tolist()})
    )
    return d / "s.json"


@pytest.mark.case("U5")
@pytest.mark.parametrize("command", ["inverse", "forward", "urdf", "mjcf", "presets"])
def test_a_broken_pipe_never_exits_0(tmp_path, command):
    """When stdout's reader has gone (``| head -c 10``), the command exits 141 (as a shell reports
    SIGPIPE) with at most one line on stderr and no traceback: never 0 with truncated output."""
    s = _states_file(tmp_path)
    argv = {
        "inverse": ["inverse", "fig1-2d", s, "--method", "matrix-factored"],
        "forward": ["forward", "fig1-2d", s, "--method", "matrix-factored"],
        "urdf": ["urdf", "fig1-2d"],
        "mjcf": ["mjcf", "fig1-2d", "--no-check"],
        "presets": ["presets"],
    }[command]
    r, w = os.pipe()
    os.close(r)  # the reader has gone before the first write
    try:
        p = subprocess.run([*EXO, *map(str, argv)], stdout=w, stderr=subprocess.PIPE, text=True, timeout=1800)
    finally:
        os.close(w)
    assert p.returncode == 141, (p.returncode, p.stderr)
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) <= 1, p.stderr
