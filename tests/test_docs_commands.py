"""Every shell command shown in README.md and docs/ runs as written (issue 38).

A fenced block marked ``sh``, ``bash``, ``shell`` or ``console`` is a list of commands (``console``: the lines
starting with ``$ ``; the other lines are the output shown). Each block runs in a fresh temporary folder, its
commands in order, as a user would type them from the checkout (``.venv/bin/...`` is this test's own
environment): every command must exit 0, and where a ``console`` block shows output, the real output has its
shape (as many lines, each starting with the shown line's first word). Inputs are shipped (presets) or made by
a command shown before (``exo-bench states PRESET -o FILE``). The README's blocks write only into
``scratch/``, which .gitignore lists (issue 48): a file left beside it fails.

The commands that take minutes, need a display or install packages are exempt, each named in
:data:`EXEMPT` with the reason, and nothing else is: an exemption that matches no shown command fails.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SHELLS = ("sh", "bash", "shell", "console")

#: A command containing one of these strings is not run; the reason says why.
EXEMPT = {
    "pip install": "installs packages into the environment (minutes; the fresh-machine commands are checked "
    "by tests/test_readme.py and run by CI's .ci/run itself)",
    "exo-bench run": "the main job: about 9 min on 2 cores (CI runs the scenes' tests instead)",
    "-m pytest": "the full test suite: this test is part of it",
    "bench --full": "the full benchmark sweep: hours",
    "dask scheduler": "starts a long-running server for several machines",
    "dask worker": "starts a long-running worker for a scheduler on another machine",
    "--scheduler tcp://": "needs the scheduler started by the command above it on another machine",
    "rerun reports/": "opens the rerun viewer (needs a display)",
    "mujoco.viewer": "opens MuJoCo's viewer (needs a display)",
}

#: A command containing one of these strings needs an optional package; without it the block is skipped.
NEEDS = {"mujoco": "mujoco", "exo-bench mjcf": "mujoco", "--format casadi": "casadi"}


def _commands(block: str, console: bool) -> tuple[list[str], list[str]]:
    """The commands of a block (continuation lines joined, comments kept for the shell) and the output lines
    a console block shows."""
    commands: list[str] = []
    shown: list[str] = []
    for line in block.replace("\\\n", " ").splitlines():
        if console and not line.startswith("$ "):
            if line.strip():
                shown.append(line)
            continue
        line = line.removeprefix("$ ").strip()
        if line and not line.startswith("#"):
            commands.append(line)
    return commands, shown


def shown_blocks() -> list[tuple[str, int, str, str]]:
    """(file, line, language, text) of every shell block of README.md and the docs' Markdown pages."""
    files = [ROOT / "README.md"] + sorted(
        p for p in (ROOT / "docs").rglob("*.md") if not {"_build", "gallery"} & set(p.relative_to(ROOT).parts)
    )
    found = []
    fence = re.compile(r"^```(\w+)[^\n]*\n(.*?)^```", re.S | re.M)
    for path in files:
        text = path.read_text()
        for m in fence.finditer(text):
            if m.group(1) in SHELLS:
                line = text.count("\n", 0, m.start()) + 1
                found.append((str(path.relative_to(ROOT)), line, m.group(1), m.group(2)))
    return found


def _exemption(command: str) -> str | None:
    return next((key for key in EXEMPT if key in command), None)


BLOCKS = shown_blocks()


def runnable(blocks: list[tuple[str, int, str, str]]) -> list[tuple[str, int, str, str]]:
    """The blocks with a command to run, each run once: a block that runs the same commands and shows the
    same output as one before it (the README's MuJoCo check, repeated in docs/guide/engines.md beside the
    viewer) is that block's run, named by both places."""
    seen: dict[tuple, int] = {}
    out: list[tuple[str, int, str, str]] = []
    for where, line, language, block in blocks:
        commands, shown = _commands(block, language == "console")
        run = tuple(c for c in commands if _exemption(c) is None)
        if not run:
            continue
        key = (tuple(tuple(shlex.split(c, comments=True)) for c in run), tuple(shown))  # comments aside
        if key in seen:
            first = out[seen[key]]
            out[seen[key]] = (f"{first[0]}:{first[1]}+{where}", line, first[2], first[3])
            continue
        seen[key] = len(out)
        out.append((where, line, language, block))
    return out


RUNNABLE = runnable(BLOCKS)


def test_the_docs_show_commands_and_every_exemption_is_used():
    """The README shows runnable commands, and each exemption matches a shown command (a stale one fails)."""
    commands = [c for b in BLOCKS for c in _commands(b[3], b[2] == "console")[0]]
    assert any(b[0] == "README.md" for b in RUNNABLE)
    unused = [key for key in EXEMPT if not any(key in c for c in commands)]
    assert not unused, f"exemptions that match no shown command: {unused}"


def test_the_readme_examples_scratch_folder_is_ignored_by_git():
    """The README's command-line examples write into scratch/, which .gitignore lists."""
    assert "scratch/" in (ROOT / ".gitignore").read_text().splitlines()
    assert any("scratch/" in b[3] for b in BLOCKS if b[0] == "README.md")


def test_every_block_with_a_command_is_run_once():
    """Running a repeated block once drops no block: each block with a runnable command is named by a run."""
    named = " ".join(f"{b[0]}:{b[1]}" for b in RUNNABLE)
    for where, line, language, block in BLOCKS:
        if any(_exemption(c) is None for c in _commands(block, language == "console")[0]):
            assert f"{where}:{line}" in named, (where, line)
    twice = [("a.md", 1, "sh", "x run  # says why\n"), ("b.md", 5, "sh", "x run\nx --mjcf=f  # mujoco.viewer\n")]
    assert [(w, n) for w, n, *_ in runnable(twice)] == [("a.md:1+b.md", 5)]


def _as_here(command: str) -> str:
    """The command with ``.venv/bin/`` pointing at this test's environment."""
    bindir = shlex.quote(str(Path(sys.executable).parent)) + "/"
    return re.sub(r"(?<![\w/])\.venv/bin/", bindir, command)


@pytest.mark.parametrize("where,line,language,block", RUNNABLE, ids=[f"{b[0]}:{b[1]}" for b in RUNNABLE])
def test_a_shown_block_runs_as_written(where, line, language, block, tmp_path):
    commands, shown = _commands(block, language == "console")
    for command in commands:
        for key, module in NEEDS.items():
            if key in command:
                pytest.importorskip(module, reason=f"`{command}` needs the optional {module}")
    outputs = []
    for command in commands:
        if _exemption(command) is not None:
            continue
        r = subprocess.run(
            ["bash", "-c", "set -euo pipefail; " + _as_here(command)],
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=600,
        )
        assert r.returncode == 0, f"{where}:{line}: `{command}` exited {r.returncode}: {r.stderr[-2000:]}"
        outputs.extend(r.stdout.splitlines())
    if where.startswith("README.md"):  # the README's examples write into scratch/ (in .gitignore), nothing else
        left = sorted(p.name for p in tmp_path.iterdir() if p.name != "scratch")
        assert not left, f"{where}:{line}: files left beside scratch/: {left}"
    if shown:
        assert len(outputs) == len(shown), f"{where}:{line}: shown {len(shown)} lines, got {outputs}"
        for got, expected in zip(outputs, shown):
            assert got.split()[:1] == expected.split()[:1], f"{where}:{line}: shown {expected!r}, got {got!r}"
