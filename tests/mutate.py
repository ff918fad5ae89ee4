"""Mutation testing of the physics modules, on demand (not in CI): ``python tests/mutate.py [MODULE...]``.

Why not mutmut: mutmut 3 runs the tests against a copy of the sources in ``mutants/`` that it puts
first on ``sys.path`` by file path, which this project's layout defeats: the import package
``exo_bench`` maps its subpackages to the top-level folders (``package-dir`` in pyproject.toml), so
the tests would import the editable install's unmutated modules. This runner is the equivalent
for that layout, with the usual operators (as mutmut's, minus string mutations):

* arithmetic ``+ - * / // % **`` swapped pairwise (``+``/``-``, ``*``/``/``, ``**``/``*``, ...);
* comparisons ``< <= > >= == != in not in is is not`` swapped with their neighbour or negation;
* ``and``/``or`` swapped, ``not x`` -> ``x``, unary minus removed;
* numbers: ``0 -> 1``, ``1 -> 0`` (ints: ``k -> k + 1``), floats ``x -> x + 1``;
* ``True``/``False`` swapped; ``return x`` -> ``return None`` is NOT used (it crashes, trivially killed);
* subscripts ``a[i]`` with an integer constant index shifted by one.

Docstrings, annotations, string constants and f-strings (messages) are not mutated. Each mutant is
written into a private copy of the package (``exo_bench`` assembled under a temporary folder and put
first on ``sys.path``, before the editable install's finder), the module's test selection runs
with ``-x`` in a forked child of a process that has imported the heavy libraries once, and the
mutant counts as killed when the selection fails (or exceeds its time limit). Survivors are printed with the line and the change; each one is
either killed by a new physics test or listed in docs/testing.md as equivalent, with the reason.

Run it niced, one module at a time (CPU heavy): ``nice python tests/mutate.py planar``.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: module -> (file, functions to mutate or None for the whole module, test selection)
TARGETS: dict[str, tuple[str, tuple[str, ...] | None, list[str]]] = {
    "planar": (
        "matrix_method/closed_forms/planar.py",
        None,
        [
            "tests/test_tolerance_sensitivity.py",
            "tests/test_planar.py",
            "tests/test_spatial.py::test_planar_closed_forms_are_the_dot_products_of_their_definition",
        ],
    ),
    "spatial": (
        "matrix_method/closed_forms/transitions.py",
        None,
        [
            "tests/test_tolerance_sensitivity.py",
            "tests/test_spatial.py::test_every_transition_gives_pinocchios_3d_matrix",
            "tests/test_spatial.py::test_a_link_that_carries_no_mass_has_finite_zero_gravity_terms",
            "tests/test_spatial.py::test_corrected_transitions_are_the_dot_products_of_their_definition",
        ],
    ),
    "coefficients": (
        "matrix_method/closed_forms/coefficients.py",
        None,
        ["tests/test_coefficients.py", "tests/test_recurrence.py", "tests/test_planar.py", "tests/test_symbolic.py"],
    ),
    "aggregates": (
        "models/mechanism/aggregates.py",
        None,
        ["tests/test_coefficients.py", "tests/test_forward_dynamics.py", "tests/test_planar.py"],
    ),
    "urdf": (
        "models/engines/urdf.py",
        ("_safe", "link_prefix", "_inertial", "_link", "_joint", "to_urdf", "pinocchio_model_size"),
        ["tests/test_urdf.py", "tests/test_pinocchio_backend.py"],
    ),
    "G": (
        "models/engines/pinocchio_backend.py",
        ("build_model", "_joint_states"),
        ["tests/test_pinocchio_backend.py", "tests/test_urdf.py"],
    ),
    "mjcf": (
        "models/engines/mjcf.py",
        ("_joint_rows", "joint_map"),
        [
            "tests/test_mujoco_drake.py::test_mjcf_ties_and_map_are_what_the_paper_coordinates_say",
            "tests/test_mujoco_drake.py::test_exported_mjcf_bodies_are_the_point_masses",
            "tests/test_mujoco_drake.py::test_forces_agree_with_every_other_method",
            "tests/test_mujoco_drake.py::test_zero_point_masses_are_exactly_zero",
            "tests/test_mujoco_drake.py::test_exported_mjcf_with_zero_masses_loads_and_places_its_bodies",
        ],
    ),
    "drake": (
        "models/engines/drake_backend.py",
        ("build_plant",),
        [
            "tests/test_mujoco_drake.py::test_drake_bodies_are_the_point_masses",
            "tests/test_mujoco_drake.py::test_forces_agree_with_every_other_method",
            "tests/test_mujoco_drake.py::test_zero_point_masses_are_exactly_zero",
        ],
    ),
    "mechanism": (
        "models/mechanism/mechanism.py",
        ("from_dict", "__post_init__"),
        ["tests/test_mechanism.py", "tests/test_bad_inputs.py"],
    ),
    "validation": (
        "models/states/validation.py",
        ("_is_number", "_finite", "validate"),
        ["tests/test_mechanism.py", "tests/test_bad_inputs.py"],
    ),
}

SWAP_BIN = {
    ast.Add: ast.Sub,
    ast.Sub: ast.Add,
    ast.Mult: ast.Div,
    ast.Div: ast.Mult,
    ast.Pow: ast.Mult,
    ast.FloorDiv: ast.Div,
    ast.Mod: ast.FloorDiv,
    ast.BitOr: ast.BitAnd,
    ast.BitAnd: ast.BitOr,
}
SWAP_CMP = {
    ast.Lt: ast.LtE,
    ast.LtE: ast.Lt,
    ast.Gt: ast.GtE,
    ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
    ast.In: ast.NotIn,
    ast.NotIn: ast.In,
    ast.Is: ast.IsNot,
    ast.IsNot: ast.Is,
}


@dataclass
class Mutant:
    index: int
    line: int
    description: str


def _protected(tree: ast.AST) -> set[int]:
    """ids of nodes never mutated: docstrings, annotations, f-strings and what is inside them."""
    out: set[int] = set()

    def mark(node):
        for n in ast.walk(node):
            out.add(id(n))

    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef, ast.Module)):
            body = node.body
            if (
                body
                and isinstance(body[0], ast.Expr)
                and isinstance(getattr(body[0], "value", None), ast.Constant)
                and isinstance(body[0].value.value, str)
            ):
                mark(body[0])
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            if node.returns is not None:
                mark(node.returns)
            for a in node.args.args + node.args.kwonlyargs + node.args.posonlyargs:
                if a.annotation is not None:
                    mark(a.annotation)
        if isinstance(node, ast.AnnAssign):
            mark(node.annotation)
        if isinstance(node, ast.JoinedStr):
            mark(node)
    return out


def _in_scope(tree: ast.Module, functions) -> set[int]:
    """ids of the nodes inside the named functions (or every node)."""
    if functions is None:
        return {id(n) for n in ast.walk(tree)}
    out: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name in functions:
            out |= {id(n) for n in ast.walk(node)}
    return out


def _sites(tree: ast.Module, functions):
    """Every (node path, kind, replacement description) that can be mutated, in source order."""
    protected, scope = _protected(tree), _in_scope(tree, functions)
    sites = []
    for node in ast.walk(tree):
        if id(node) in protected or id(node) not in scope:
            continue
        line = getattr(node, "lineno", 0)
        if isinstance(node, ast.BinOp) and type(node.op) in SWAP_BIN:
            sites.append((node, "binop", line, f"{type(node.op).__name__} -> {SWAP_BIN[type(node.op)].__name__}"))
        elif isinstance(node, ast.AugAssign) and type(node.op) in SWAP_BIN:
            sites.append((node, "augop", line, f"{type(node.op).__name__}= -> {SWAP_BIN[type(node.op)].__name__}="))
        elif isinstance(node, ast.Compare):
            for k, op in enumerate(node.ops):
                if type(op) in SWAP_CMP:
                    sites.append(((node, k), "cmp", line, f"{type(op).__name__} -> {SWAP_CMP[type(op)].__name__}"))
        elif isinstance(node, ast.BoolOp):
            sites.append(
                (node, "boolop", line, f"{type(node.op).__name__} -> {'Or' if isinstance(node.op, ast.And) else 'And'}")
            )
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.Not)):
            sites.append((node, "unary", line, f"remove {type(node.op).__name__}"))
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float, bool):
            v = node.value
            new = (not v) if isinstance(v, bool) else (1 if v == 0 else 0 if v == 1 else v + 1)
            sites.append((node, "const", line, f"{v!r} -> {new!r}"))
    sites.sort(key=lambda s: (s[2], s[3]))
    return sites


class _Apply(ast.NodeTransformer):
    def __init__(self, target, kind):
        self.target, self.kind = target, kind

    def generic_visit(self, node):
        node = super().generic_visit(node)
        t = self.target[0] if self.kind == "cmp" else self.target
        if node is not t:
            return node
        if self.kind in ("binop", "augop"):
            node.op = SWAP_BIN[type(node.op)]()
        elif self.kind == "cmp":
            k = self.target[1]
            node.ops[k] = SWAP_CMP[type(node.ops[k])]()
        elif self.kind == "boolop":
            node.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        elif self.kind == "unary":
            return node.operand
        elif self.kind == "const":
            v = node.value
            node.value = (not v) if isinstance(v, bool) else (1 if v == 0 else 0 if v == 1 else v + 1)
        return node


def mutants(source: str, functions):
    """Yield ``(Mutant, mutated source)`` for every site of the module."""
    tree = ast.parse(source)
    for index, (_, kind, line, desc) in enumerate(_sites(tree, functions)):
        t = ast.parse(source)
        site = _sites(t, functions)[index]
        new = ast.fix_missing_locations(_Apply(site[0], kind).visit(t))
        yield Mutant(index, line, f"{kind}: {desc}"), ast.unparse(new)


def _assemble(tmp: Path) -> None:
    """A private copy of the import package and the tests, importable as ``exo_bench``."""
    pkg = tmp / "exo_bench"
    pkg.mkdir()
    shutil.copy(ROOT / "exo_bench" / "__init__.py", pkg / "__init__.py")
    for sub in ("models", "matrix_method", "lagrange", "bench"):
        shutil.copytree(ROOT / sub, pkg / sub, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "tests", tmp / "tests", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(ROOT / "docs", tmp / "docs", ignore=shutil.ignore_patterns("__pycache__"))
    for f in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / f, tmp / f)


_PRELOADED = False


def _preload() -> None:
    """Import the heavy libraries once in this process; every mutant's test run is a fork of it
    (a fresh interpreter per mutant would spend seconds importing them again)."""
    global _PRELOADED
    if not _PRELOADED:
        import hypothesis, matplotlib, numpy, pinocchio, pytest, scipy.integrate, sympy  # noqa: F401,E401

        matplotlib.use("Agg")
        _PRELOADED = True


def _run_tests(tmp: Path, tests: list[str], timeout: float) -> bool:
    """True when the selection passes (the mutant survives). The tests run in a forked child that
    imports ``exo_bench`` from ``tmp`` (nothing of it is imported in this parent)."""
    _preload()
    pid = os.fork()
    if pid == 0:  # child: never returns
        code = 3
        try:
            os.chdir(tmp)
            sys.path.insert(0, str(tmp))
            sys.path.insert(0, str(tmp / "tests"))
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.dup2(devnull, 2)
            import pytest

            code = int(pytest.main(["-x", "-q", "-p", "no:cacheprovider", *tests]))
        finally:
            os._exit(code)
    deadline = time.monotonic() + timeout
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status) == 0
        if time.monotonic() > deadline:
            os.kill(pid, 9)
            os.waitpid(pid, 0)
            return False
        time.sleep(0.05)


def run(name: str, timeout: float, only: list[int] | None = None) -> dict:
    path, functions, tests = TARGETS[name]
    with tempfile.TemporaryDirectory(prefix=f"mutate-{name}-") as d:
        tmp = Path(d)
        _assemble(tmp)
        target = tmp / "exo_bench" / path
        original = target.read_text()
        t0 = time.perf_counter()
        if not _run_tests(tmp, tests, timeout * 4):
            raise SystemExit(f"{name}: the test selection fails without any mutant: {tests}")
        baseline = time.perf_counter() - t0
        killed, survived = [], []
        for m, src in mutants(original, functions):
            if only is not None and m.index not in only:
                continue
            target.write_text(src)
            (killed if not _run_tests(tmp, tests, max(timeout, 3 * baseline)) else survived).append(m)
            status = "survived" if survived and survived[-1] is m else "killed"
            print(f"{name} #{m.index} line {m.line} {m.description}: {status}", flush=True)
        target.write_text(original)
    total = len(killed) + len(survived)
    return {
        "module": name,
        "file": path,
        "functions": functions,
        "tests": tests,
        "mutants": total,
        "killed": len(killed),
        "survived": [vars(m) for m in survived],
        "score": len(killed) / total if total else 1.0,
    }


BEGIN, END = "<!-- mutation:begin (tests/mutate.py --write) -->", "<!-- mutation:end -->"


def _equivalent(doc: str) -> dict[tuple[str, str], str]:
    """The equivalent mutants listed in docs/testing.md: ``(module, "line L <description>") -> reason``
    from its table rows ``| module | line L | description | reason |``."""
    out = {}
    for row in doc.splitlines():
        cells = [c.strip() for c in row.strip().strip("|").split("|")]
        if len(cells) == 4 and cells[1].startswith("line "):
            out[(cells[0], f"{cells[1]} {cells[2]}")] = cells[3]
    return out


def write_summary(results: list[dict], doc_path: Path) -> None:
    """Put the per-module table between the markers of ``doc_path``: mutants, killed, survivors that
    the document lists as equivalent, others, and the score over the non-equivalent mutants."""
    doc = doc_path.read_text()
    equivalent = _equivalent(doc)
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    lines = [
        BEGIN,
        "",
        f"Generated by `python tests/mutate.py --write docs/testing.md RESULTS.json...` at commit {commit}.",
        "",
        "| module | file (scope) | mutants | killed | equivalent | surviving, not equivalent | score (non-equivalent killed) |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for r in results:
        surv = [f"line {m['line']} {m['description']}" for m in r["survived"]]
        eq = [x for x in surv if (r["module"], x) in equivalent]
        other = [x for x in surv if (r["module"], x) not in equivalent]
        denominator = r["mutants"] - len(eq)
        scope = r["file"] + (f" ({', '.join(r['functions'])})" if r["functions"] else "")
        score = 100.0 * r["killed"] / denominator if denominator else 100.0
        lines.append(
            f"| {r['module']} | {scope} | {r['mutants']} | {r['killed']} | {len(eq)} | {len(other)} | {score:.1f}% |"
        )
        for x in other:
            lines.append(f"| {r['module']} | NOT EXPLAINED: {x} | | | | | |")
    lines += ["", END]
    i, j = doc.index(BEGIN), doc.index(END) + len(END)
    doc_path.write_text(doc[:i] + "\n".join(lines) + doc[j:])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("modules", nargs="*", default=list(TARGETS), help=f"among {', '.join(TARGETS)}")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds per mutant at least")
    ap.add_argument("--only", type=int, nargs="*", help="mutant indices to run (after a fix)")
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("--list", action="store_true", help="list the mutants, run nothing")
    ap.add_argument(
        "--write", metavar="DOC", help="with RESULTS.json files as arguments: write the score table into DOC"
    )
    args = ap.parse_args(argv)
    if args.write:
        results = [r for f in args.modules for r in json.loads(Path(f).read_text())]
        write_summary(results, Path(args.write))
        return 0
    results = []
    for name in args.modules:
        if args.list:
            path, functions, _ = TARGETS[name]
            for m, _ in mutants((ROOT / path).read_text(), functions):
                print(f"{name} #{m.index} line {m.line} {m.description}")
            continue
        r = run(name, args.timeout, args.only)
        results.append(r)
        print(
            f"== {name}: {r['killed']}/{r['mutants']} killed ({100 * r['score']:.1f}%), {len(r['survived'])} survived",
            flush=True,
        )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
