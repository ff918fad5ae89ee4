"""The README's two fresh-machine commands, and CI running exactly the second one."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _commands():
    text = (ROOT / "README.md").read_text()
    section = text.split("## On a fresh machine", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"```sh\n(.*?)\n```", section, re.S)


def test_readme_has_exactly_two_fresh_machine_commands():
    cmds = _commands()
    assert len(cmds) == 2 and all("\n" not in c for c in cmds)
    assert cmds[0].startswith("python3 -m venv") and "exo-bench run" in cmds[0]
    assert cmds[1].startswith("python3 -m venv") and "pytest" in cmds[1]


def test_ci_runs_the_readmes_test_command():
    assert _commands()[1] in (ROOT / ".ci/run").read_text().splitlines()
