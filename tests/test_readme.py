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


def run_example(heading: str, tmp_path):
    """The one ```python block of the README's section ``heading``, run as a user would run it."""
    import subprocess
    import sys

    text = (ROOT / "README.md").read_text()
    section = text.split(f"## {heading}", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)\n```", section, re.S)
    assert len(blocks) == 1
    script = tmp_path / "example.py"
    script.write_text(blocks[0])
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return r


def test_the_library_example_runs_and_checks_itself(tmp_path):
    """The README's "Use it as a library" example, run as a user would run it (its own asserts
    compare the methods with each other and a forward-dynamics step with the prescribed qdd)."""
    run_example("Use it as a library", tmp_path)
