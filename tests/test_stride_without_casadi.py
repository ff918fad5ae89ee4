"""The human stride's scene runs from its stored strides with ``pip install -e .`` alone (the README's first
command installs no casadi: casadi is the ``[test]``/solver extra). The join section (bench/studies/stride/
constraints.py, its :func:`~exo_bench.bench.studies.stride.constraints.load_jump`) once imported the transcription,
which imports casadi, so the main job's ``human-2d-stride`` scene failed on a fresh clone with "No module named
'casadi'" while every test passed (the test environment has casadi). Here casadi is made unimportable in a
child process, and the report's section is built there for every stored stride."""

from __future__ import annotations

import json
import subprocess
import sys

SCRIPT = """
import json, sys
sys.modules["casadi"] = None  # import casadi -> ModuleNotFoundError, as without the extra
from exo_bench.bench.studies.stride import constraints, data
from exo_bench.bench.studies.stride.report import TRIALS, _stored
from exo_bench.models.mechanism.presets import human
M = human(2)
groups = constraints.joins(M, _stored(M), TRIALS)
print(json.dumps({"casadi": sys.modules["casadi"] is None, "joins": [len(g) for g in groups],
                  "section": "\\n".join(constraints.section(groups))}))
"""


def test_the_stride_reports_join_section_needs_no_casadi():
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["casadi"] is True  # still blocked at the end: nothing imported it through another name
    assert len(got["joins"]) == 4 and all(n >= 1 for n in got["joins"]), got["joins"]  # 4 stored strides
    assert "join" in got["section"], got["section"][:500]
