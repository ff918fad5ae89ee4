"""Every ```python block of docs/*.md runs as written (a newcomer copies it).

Each block runs in a fresh interpreter in a temporary folder, with nothing defined before it: a block that
uses a name it does not define (a sketch) fails here. The README's one block is run by tests/test_readme.py,
and the gallery's scripts by the docs build (.ci/docs).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BLOCKS = [
    pytest.param(block, id=f"{path.relative_to(ROOT)}#{k}")
    for path in sorted((ROOT / "docs").rglob("*.md"))
    for k, block in enumerate(re.findall(r"```python\n(.*?)\n```", path.read_text(encoding="utf-8"), re.S))
]


def test_the_docs_have_python_blocks():
    assert BLOCKS, "no ```python block found under docs/: the glob or the pattern is wrong"


@pytest.mark.parametrize("block", BLOCKS)
def test_a_docs_python_block_runs_as_written(block: str, tmp_path: Path):
    r = subprocess.run([sys.executable, "-c", block], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, f"the block failed:\n{block}\n--- stderr ---\n{r.stderr[-2000:]}"
