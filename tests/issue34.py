"""Issue 34's findings, one id each, and where their tests are.

A test reproduces a finding by carrying ``@pytest.mark.case("S1")`` (several ids are allowed:
``@pytest.mark.case("S1", "T2")``); a case of tests/test_bad_inputs.py's :data:`CASES` does it with
``issue="34:S1"``. docs/errors.md lists every finding with the tests found here (:func:`marked_tests`,
read from the test files' source, so a test that is renamed or removed leaves the document), and
tests/test_bad_inputs.py::test_every_issue_34_finding_has_a_test fails while a finding has none.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: id -> what the probe of a fresh clone found (issue 34's words, shortened).
FINDINGS: dict[str, str] = {
    "S1": "link and mechanism names went raw into the MJCF's XML comments: a name could add a body or include a file",
    "S2": "the mechanism name went raw into LaTeX: `\\immediate\\write18{...}` appeared verbatim in the .tex",
    "S3": "`stability --full` unpickled checkpoints found beside the reports folder",
    "S4": "a symlink planted in an output folder redirected the write; an atomic replace reset the file's mode",
    "S5": "a step scene's mechanism name was used as a path (`../../x`, absolute `*.npz` names)",
    "W2": "`forward` with newton-euler at a rod length of 1e-300 returned inf and NaN, exit 0",
    "W3": "near-singular forward dynamics had no conditioning check: answers off by 7.6 to 78.6, no word",
    "W4": "`derivatives.forward_dynamics` returned NaN or inf where `forward_dynamics` refuses",
    "W5": "with `check=False`, an `out` partly overlapping an input gave garbage",
    "W6": "the Mechanism's arrays were writable, and writing to them changed some methods but not others",
    "W7": "a step scene reused the stored step of any mechanism named exo5-3d",
    "W8": "numeric strings in states were read as numbers; lists of str, bytes, Decimal and Fraction were accepted",
    "W9": "a labelled DataFrame was read by position; a masked array's masked entries were used",
    "W10": "a mechanism named `numpy` produced numpy.py, which imports itself; `math` produced math.h",
    "D1": "concurrent `exo-bench run`s into one reports folder lost scenes and files, exit 0",
    "D2": "a scene named `summary` lost its page",
    "D3": "a scene named like a suite report (errata, stability, scaling, paper_table...) replaced that report",
    "D4": "two scenes with one name in one run: the first vanished",
    "D5": "`simulate()` stopped by a budget kept only t = 0",
    "D6": "`-o /dev/stdout >> app.log` replaced app.log",
    "D7": "`urdf m.json -o m.json` overwrote its own input",
    "D8": "a runs.json of the right format but wrong types threw away a whole run with an internal error",
    "D9": "a sweep whose workers refused its rows (another commit) replaced the published reports with error rows",
    "C1": '`prepare(..., "pinocchio", threads=1000)` under a memory limit exited through libgomp',
    "H1": "`simulate()` hung with `t_span=(0, nan)`, `rtol=0` or `rtol=nan`; no default budget",
    "H2": "`--scheduler` at a port that never speaks hung past 180 s; garbage gave 'Unable to allocate 3.07 EiB'",
    "L1": "an .npz with a member named `q` beside a small `q.npy` passed the header check and used 1.5 GB",
    "L2": "`forward` checked `--max-time` and `--max-memory` only after reading",
    "L3": "`--workers` and `threads` had no upper bound",
    "T1": "a SIGTERM landing in a GC callback was swallowed and the run finished with exit 0",
    "T2": "a surrogate in a name gave 'internal error: TypeError' in mjcf and a codec error elsewhere",
    "T3": "a sweep checkpoint of valid JSON that is not an object gave an internal error without the file's name",
    "T4": "`NUMBA_DISABLE_JIT=1` gave 'internal error: NotImplementedError: <intrinsic tile_in>'",
    "T5": "the derivatives gave raw reshape and CasADi errors on 0 samples, mismatched counts or massless links",
    "U2": "the mechanism's own name was never validated (NUL, dicts and numbers passed)",
    "U3": "Ctrl-C in `gait --solve` reported 'IPOPT did not solve' instead of 'interrupted'",
    "U4": "'No space left on device' named no path",
    "U5": "`| head -c 10` exited 0 with truncated JSON",
    "U6": "NUMBA_NUM_THREADS=0 and NUMBA_THREADING_LAYER errors did not name the variable",
    "U7": "`mjcf` of a 100,000-link flat tree tried to allocate 447 GiB without an estimate",
    "U8": "a ragged list of ndarray rows gave numpy's raw message; `None` was reported as 'got nan'",
    "U9": "scene names of a space, U+202E, U+0085 or U+2028 became spoofable file names",
    "U10": "duplicate methods or outputs in a scene produced duplicate rows",
    "U11": "`-o ''` wrote stdout, `-o newdir/` created a file, `-o -` created a file named `-`",
    "U12": "`simulate(max_seconds=-1)` was accepted",
    "F1": "the README's test command flaked: `test_lagrange_budget` raced a 50 ms budget",
    "F2": "the README's test command flaked: `test_estimate_vs_measured` compared wall-clock and memory on a loaded machine",
    # The probe of the surfaces added since (f_ext, human model and contact, stride CLI, derivatives).
    "P1": "`f_ext` of strings, Decimals, booleans, complex numbers or masked entries was read as numbers",
    "P2": "with `f_ext`, forward dynamics and its derivatives read a `tau` of strings, Decimals or complex numbers",
    "P3": "`f_ext` of 1e308 N: inverse dynamics returned inf and NaN, forward dynamics blamed `tau`",
    "P4": "contact points of strings, booleans or Decimals, huge ints as body mass: raw TypeError or OverflowError",
    "P5": "a ground mask of the strings 'False' put every point in contact; unequal sample counts broadcast",
    "P6": "the inverse-dynamics JVP and VJP returned NaN and inf with check=True for finite huge directions",
    "P7": "with check=False the derivatives read states of strings, booleans or Decimals as numbers",
    "P8": "an edited stored stride (string arrays, reversed times, a meta of another speed) was described as valid",
    "P9": "the derivatives copied the states before their memory estimate: a raw MemoryError at 10^9 samples",
}


def _case_ids(decorator: ast.expr) -> list[str]:
    """The ids of ``pytest.mark.case("S1", ...)``, or []."""
    if not isinstance(decorator, ast.Call):
        return []
    f = decorator.func
    if isinstance(f, ast.Attribute) and f.attr == "case" and ast.unparse(f.value) in ("pytest.mark", "mark"):
        return [a.value for a in decorator.args if isinstance(a, ast.Constant) and isinstance(a.value, str)]
    return []


def marked_tests() -> dict[str, list[tuple[str, str]]]:
    """id -> ``(path::test, summary)`` of every test function marked with it (the summary is its
    docstring's first sentence), and ``(path::test_bad_input[case], "")`` of every bad-input case whose
    ``issue`` is ``"34:<id>"``, in file order."""
    found: dict[str, list[tuple[str, str]]] = {}
    for path in sorted((ROOT / "tests").glob("test_*.py")) + sorted((ROOT / "bench").glob("test_*.py")):
        tree = ast.parse(path.read_text(), str(path))
        rel = path.relative_to(ROOT).as_posix()
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                for dec in node.decorator_list:
                    for ident in _case_ids(dec):
                        doc = " ".join((ast.get_docstring(node) or "").split())
                        summary = doc.split(". ")[0].rstrip(".")
                        found.setdefault(ident, []).append((f"{rel}::{node.name}", summary))
            if isinstance(node, ast.Call) and ast.unparse(node.func) == "Case":
                kw = {k.arg: k.value for k in node.keywords}
                issue, ident = kw.get("issue"), kw.get("id")
                if ident is None and node.args and isinstance(node.args[0], ast.Constant):
                    ident = node.args[0]
                if (
                    isinstance(issue, ast.Constant)
                    and isinstance(issue.value, str)
                    and issue.value.startswith("34:")
                    and isinstance(ident, ast.Constant)
                ):
                    found.setdefault(issue.value[3:], []).append((f"{rel}::test_bad_input[{ident.value}]", ""))
    return found
