"""One call path (issue 35): the public calls are defined once, in PreparedModel; a method supplies
kernels (objects listed in its MethodSpec) and never overrides a public call; no code outside the
method table compares a method's or a kernel's name; nothing rebinds a public call on an instance."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from exo_bench.api import prepare
from exo_bench.api.methods import METHODS
from exo_bench.models.runtime.prepared import Kernel
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.runtime.prepared import PreparedModel
from exo_bench.models.mechanism.presets import exo5

ROOT = Path(__file__).resolve().parents[1]
#: The package's sources (the import package's subpackages are these top-level folders).
PACKAGE = ("exo_bench", "models", "matrix_method", "lagrange", "bench")
#: The table and the modules that define kernel objects: the only places that may name them.
TABLE = {
    "exo_bench/api/methods.py",
    "models/runtime/prepared.py",
    "matrix_method/kernels.py",
    "models/newton_euler/kernels.py",
}
#: Where the same words name something else than a method of the table or a kernel: the routes of
#: symbolic composition (the size study, the paper's table of composition rows, bench/test_compose.py's),
#: and sympy's LagrangesMethod or KanesMethod (the sympy peer's ``kind``). Each file, the words it may compare.
OTHER_MEANING = {
    "bench/studies/equations_size.py": {"matrix", "lagrange"},
    "bench/perf/reports/paper_table.py": {"matrix", "lagrange"},
    "lagrange/peer.py": {"lagrange"},
}
PUBLIC_CALLS = ("inverse_dynamics", "forward_dynamics", "mass_matrix", "bias_forces", "mass_matrix_and_bias")


def _sources() -> dict[str, ast.Module]:
    """Every library module of the package, parsed (benchmark rows, bench/test_*.py, are tests)."""
    out = {}
    for top in PACKAGE:
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).as_posix()
            if path.name.startswith("test_") or "__pycache__" in rel:
                continue
            out[rel] = ast.parse(path.read_text(), rel)
    return out


def _names() -> set[str]:
    """Every method's name and every kernel's, read from the table."""
    kernels = {k.name for s in METHODS.values() for k in s.kernels} | {
        k.option for s in METHODS.values() for k in s.kernels
    }
    return set(METHODS) | kernels


def _literals(node: ast.AST) -> list[str]:
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node.value]
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return [e.value for e in node.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)]
    return []


def name_comparisons(tree: ast.Module, names: set[str]) -> list[tuple[int, str]]:
    """``(line, name)`` of each comparison of a string literal naming a method or a kernel."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            for side in (node.left, *node.comparators):
                found += [(node.lineno, s) for s in _literals(side) if s in names]
    return found


def test_names_are_compared_only_in_the_table():
    names = _names()
    assert {"matrix-factored", "newton-euler", "numba", "numpy"} <= names
    found = [
        f"{rel}:{line}: {name!r}"
        for rel, tree in _sources().items()
        if rel not in TABLE
        for line, name in name_comparisons(tree, names)
        if name not in OTHER_MEANING.get(rel, ())
    ]
    assert not found, "branches on a method's or a kernel's name outside the table:\n" + "\n".join(found)


def test_the_name_finder_finds_a_comparison():
    """The finder above can fail: it finds the branches it is meant to forbid."""
    tree = ast.parse('if method == "lagrange" or kernel in ("numba", "x"):\n    pass\n')
    assert name_comparisons(tree, {"lagrange", "numba"}) == [(1, "lagrange"), (1, "numba")]


def _prepared_classes(sources: dict[str, ast.Module]) -> dict[str, tuple[str, ast.ClassDef]]:
    """Every class of the package that derives from PreparedModel (by the names of its bases)."""
    classes = {
        node.name: (rel, node)
        for rel, tree in sources.items()
        for node in ast.walk(tree)
        if isinstance(node, ast.ClassDef)
    }

    def bases(node: ast.ClassDef) -> list[str]:
        return [b.attr if isinstance(b, ast.Attribute) else getattr(b, "id", "") for b in node.bases]

    derived, grew = {"PreparedModel"}, True
    while grew:
        grew = False
        for name, (_, node) in classes.items():
            if name not in derived and derived & set(bases(node)):
                derived.add(name)
                grew = True
    return {n: classes[n] for n in derived if n in classes}


def _defines(node: ast.ClassDef, call: str) -> bool:
    for item in node.body:
        if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)) and item.name == call:
            return True
        targets = (
            item.targets if isinstance(item, ast.Assign) else [item.target] if isinstance(item, ast.AnnAssign) else []
        )
        if any(isinstance(t, ast.Name) and t.id == call for t in targets):
            return True
    return False


def test_each_public_call_is_defined_once_in_the_base_class():
    classes = _prepared_classes(_sources())
    assert {"PreparedModel", "MatrixFactored", "NewtonEuler", "LagrangeModel"} <= set(classes)
    for call in PUBLIC_CALLS:
        where = [f"{rel}:{name}" for name, (rel, node) in sorted(classes.items()) if _defines(node, call)]
        assert where == ["models/runtime/prepared.py:PreparedModel"], f"{call} is defined in {where}"


#: (method, kernel option) of every method with kernels, each option.
_KERNELLED = [(m, o) for m, s in METHODS.items() for o in s.kernel_options]


@pytest.mark.parametrize("method,option", _KERNELLED)
def test_no_instance_attribute_shadows_a_public_call(method, option):
    """After one-sample calls of every form (the lean entry's first use included), the public calls
    are still the class's: nothing was rebound on the instance."""
    mech = exo5(3)
    model = prepare(mech, method, kernel=option)
    mo = smooth_random_motion(mech, np.linspace(0.0, 1.0, 3), seed=1)
    q, qd, qdd = (np.ascontiguousarray(a[0]) for a in (mo.q, mo.qd, mo.qdd))
    out = np.empty(mech.dof)
    first = model.inverse_dynamics(q, qd, qdd, check=False, out=out).copy()
    for _ in range(2):
        assert np.array_equal(model.inverse_dynamics(q, qd, qdd, check=False, out=out), first)
        assert np.array_equal(model.inverse_dynamics(q, qd, qdd, check=False), first)
        assert np.array_equal(model.inverse_dynamics(q, qd, qdd), first)
        model.forward_dynamics(q, qd, first, check=False)
    shadowed = sorted(set(vars(model)) & set(PUBLIC_CALLS))
    assert not shadowed, f"{method} ({option}): instance attributes shadow {shadowed}"
    for call in PUBLIC_CALLS:
        assert getattr(type(model), call) is getattr(PreparedModel, call), f"{method} overrides {call}"


def test_every_kernel_states_what_it_computes_for_which_shapes_its_cost_and_threading():
    kernels = [k for s in METHODS.values() for k in s.kernels]
    assert kernels, "no method lists a kernel object"
    for k in kernels:
        assert isinstance(k, Kernel)
        assert k.computes and set(k.computes) <= set(PUBLIC_CALLS), k
        assert k.shapes and k.cost and k.threading, k
    for name in ("matrix-factored", "newton-euler"):
        s = METHODS[name]
        assert s.kernel_options == ("numba", "numpy"), s.kernel_options  # the user-facing option, default first
        assert len(s.kernels) > 2, f"{name}: its numba option runs several kernels, each an object"


@pytest.mark.parametrize("method", [m for m, s in METHODS.items() if s.kernels])
def test_the_table_and_the_class_list_the_same_kernels(method):
    """One list per method: its MethodSpec's kernels are its prepared-model class's, and the option
    ``kernel`` takes exactly their options."""
    spec = METHODS[method]
    cls = spec.load()
    assert cls.kernels is spec.kernels
    with pytest.raises(ValueError, match=r"option 'kernel': expected one of 'numba', 'numpy', got 'jax'"):
        prepare(exo5(2), method, kernel="jax")
