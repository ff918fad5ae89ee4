"""Every per-method fact comes from one table, :data:`exo_bench.api.methods.METHODS` (issue 21).

No library module outside ``exo_bench/api/methods.py`` keeps its own table keyed by method names
(a dict with two or more method names as keys, or a tuple, list or set of two or more of them):
such a table is how a colour, a known-wrong warning or a kernel list went stale before. What a
benchmark or a study chooses to run (a sweep's profile, a case's methods) is a choice, not a fact,
and lives where it is chosen: those modules are listed in ``CHOICES``.
"""

from __future__ import annotations

import ast
from pathlib import Path

from exo_bench.api import METHODS, spec
from exo_bench.api.methods import compiled_methods, known_wrong, preference

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ("exo_bench", "models", "matrix_method", "lagrange", "bench")
#: Modules that choose which methods to run (not facts about a method).
CHOICES = {"bench/test_inverse_dynamics.py", "bench/test_memory.py", "bench/test_compose.py", "bench/perf/profiles.py"}
#: Single literals that choose what a report shows: (module, the method names in the literal).
CHOSEN = {
    ("bench/studies/equations_size.py", ("lagrange", "matrix")),  # the size study's routes and their styles
    ("bench/perf/reports/paper_table.py", ("lagrange", "matrix", "recurrence")),  # the paper table's columns
    ("bench/perf/reports/paper_table.py", ("matrix", "matrix-factored")),  # the exo5-3d ratio's rows
    ("bench/studies/errata.py", ("lagrange", "pinocchio")),  # the errata study's witnesses
    ("bench/perf/peers.py", ("matrix-factored", "newton-euler")),  # the denominators of the engines' ratios
    ("bench/test_external_forces.py", ("matrix-factored", "newton-euler")),  # the f_ext rows' two one-sample paths
}


def _tables(path: Path) -> list[str]:
    names = set(METHODS)
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Dict):
            items = node.keys
        elif isinstance(node, (ast.Tuple, ast.List, ast.Set)):
            items = node.elts
        else:
            continue
        hits = [e.value for e in items if isinstance(e, ast.Constant) and e.value in names]
        rel = str(path.relative_to(ROOT))
        if len(set(hits)) >= 2 and (rel, tuple(sorted(set(hits)))) not in CHOSEN:
            found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {sorted(set(hits))}")
    return found


def test_no_per_method_table_outside_the_method_table():
    found = []
    for top in LIBRARY:
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = str(path.relative_to(ROOT))
            if rel == "exo_bench/api/methods.py" or rel in CHOICES or ".venv" in path.parts:
                continue
            found += _tables(path)
    assert not found, "per-method tables outside exo_bench/api/methods.py:\n" + "\n".join(found)


def test_the_table_is_complete():
    for name, s in METHODS.items():
        assert s.name == name and s.text and s.colour and s.cost is not None, name
        assert s.load().method == name, name
    assert len({s.colour for s in METHODS.values()}) == len(METHODS)
    assert preference()[0] == "matrix-factored" and "matrix-paper" not in preference()
    assert set(known_wrong()) == {"matrix-paper"}
    assert set(compiled_methods()) == {m for m, s in METHODS.items() if s.kernels} and spec("matrix").compiled
