"""numba's runtime set-up lives in one module (issue 35): models/machine/numba_runtime.py patches numba's internals
and chooses its threading layer, in :func:`~exo_bench.models.machine.numba_runtime.ensure`, and no other module
of the library does; no module that compiles kernels keeps mutable module state; importing the runtime
module changes nothing; ``ensure`` is idempotent.

The scans read the source (ast), so they count what the code does, not what one run happened to execute.
"""

from __future__ import annotations

import ast
import importlib.util
import json
import subprocess
import sys
from pathlib import Path


def _package_dir(name: str) -> Path:
    spec = importlib.util.find_spec(name)
    assert spec is not None and spec.submodule_search_locations, name
    return Path(list(spec.submodule_search_locations)[0])


#: The library's sources (not bench/, the layer above: a benchmark may choose a threading layer on purpose),
#: found where the package is imported from (a checkout or a copy of the package).
LIBRARY = sorted(
    {
        *(
            p
            for d in ("models", "matrix_method", "lagrange", "api")
            for p in _package_dir(f"exo_bench.{d}").rglob("*.py")
        ),
        _package_dir("exo_bench") / "__init__.py",
    }
)
RUNTIME = _package_dir("exo_bench.models") / "machine" / "numba_runtime.py"
#: Calls that change a container in place.
MUTATORS = {"append", "extend", "insert", "update", "setdefault", "pop", "popitem", "clear", "add", "discard", "remove"}


def _root(node: ast.AST) -> str | None:
    """The name an expression hangs from: ``a`` of ``a.b[c].d(e).f``."""
    while True:
        if isinstance(node, ast.Name):
            return node.id
        if isinstance(node, (ast.Attribute, ast.Subscript)):
            node = node.value
        elif isinstance(node, ast.Call):
            getattr_of = isinstance(node.func, ast.Name) and node.func.id == "getattr" and node.args
            node = node.args[0] if getattr_of else node.func
        elif isinstance(node, ast.IfExp):
            node = node.body
        elif isinstance(node, ast.BoolOp):
            node = node.values[0]
        else:
            return None


def _aliases(tree: ast.Module, names: set[str]) -> set[str]:
    """``names`` and every name assigned from an expression that hangs from one of them
    (``config = numba.config``, ``files = KERNEL_DIRS[folder]``), to a fixed point."""
    names = set(names)
    while True:
        more = {
            t.id
            for node in ast.walk(tree)
            if isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None and _root(node.value) in names
            for t in (node.targets if isinstance(node, ast.Assign) else [node.target])
            if isinstance(t, ast.Name)
        }
        if more <= names:
            return names
        names |= more


def _numba_names(tree: ast.Module) -> set[str]:
    """Names bound to numba or llvmlite: imported from them, or aliases of those."""
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {
                (a.asname or a.name).split(".")[0] for a in node.names if a.name.split(".")[0] in ("numba", "llvmlite")
            }
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in ("numba", "llvmlite"):
            names |= {a.asname or a.name for a in node.names}
    return _aliases(tree, names)


def _changes(tree: ast.Module, owners: set[str], inside_functions_only: bool = False) -> list[str]:
    """Every statement that changes an object hanging from one of ``owners``: an assignment to its
    attribute or item, a mutating call, ``setattr``."""
    scopes = (
        [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
        if inside_functions_only
        else [tree]
    )
    found = []
    for scope in scopes:
        for node in ast.walk(scope):
            targets: list[ast.AST] = []
            if isinstance(node, ast.Assign):
                targets = [e for t in node.targets for e in (t.elts if isinstance(t, ast.Tuple) else [t])]
            elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
                targets = [node.target]
            for t in targets:
                if isinstance(t, (ast.Attribute, ast.Subscript)) and _root(t) in owners:
                    found.append(f"{node.lineno}: {ast.unparse(t)} =")
            if isinstance(node, ast.Call):
                f = node.func
                if isinstance(f, ast.Attribute) and f.attr in MUTATORS and _root(f.value) in owners:
                    found.append(f"{node.lineno}: {ast.unparse(f)}()")
                if isinstance(f, ast.Name) and f.id == "setattr" and node.args and _root(node.args[0]) in owners:
                    found.append(f"{node.lineno}: setattr({ast.unparse(node.args[0])}, ...)")
    return found


def _name(path: Path) -> str:
    return "/".join(path.parts[-3:])


def _numba_patches(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    return _changes(tree, _numba_names(tree))


def test_the_scan_finds_the_runtime_modules_patches():
    """The scan can fail: in numba_runtime.py it finds the three (the locator list, the index key, the
    threading layer)."""
    found = " ".join(_numba_patches(RUNTIME))
    for patch in ("_locator_classes.insert()", "FunctionCache._index_key =", "THREADING_LAYER ="):
        assert patch in found, found


def test_no_other_module_patches_numba():
    """Outside numba_runtime.py no module of the library assigns to, or changes in place, anything of
    numba's or llvmlite's (its internals, its config)."""
    found = {_name(p): hits for p in LIBRARY if p != RUNTIME and (hits := _numba_patches(p))}
    assert found == {}, found


def _imports_numba(tree: ast.Module) -> bool:
    return bool(_numba_names(tree))


def test_no_kernel_module_keeps_mutable_module_state():
    """A module that uses numba neither rebinds a module global (``global``) nor changes a module-level
    object from inside a function: the runtime's state is numba's own and numba_runtime.RUNTIME's."""
    found = {}
    for p in LIBRARY:
        tree = ast.parse(p.read_text())
        if not _imports_numba(tree):
            continue
        module_names = {
            t.id
            for node in tree.body
            if isinstance(node, (ast.Assign, ast.AnnAssign))
            for t in (node.targets if isinstance(node, ast.Assign) else [node.target])
            if isinstance(t, ast.Name)
        }
        hits = [f"{n.lineno}: global {', '.join(n.names)}" for n in ast.walk(tree) if isinstance(n, ast.Global)]
        hits += _changes(tree, _aliases(tree, module_names), inside_functions_only=True)
        if hits:
            found[_name(p)] = hits
    assert found == {}, found


def test_importing_the_runtime_module_imports_no_numba():
    """Its import checks nothing and patches nothing: numba is not even imported."""
    code = (
        "import json, sys\nfrom exo_bench.models.machine import numba_runtime\n"
        "print(json.dumps(sorted(m for m in ('numba', 'llvmlite') if m in sys.modules)))"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert json.loads(r.stdout.strip().splitlines()[-1]) == []


def test_ensure_is_idempotent():
    """Called again, ``ensure`` installs no second locator and wraps numba's index key once."""
    from numba.core import caching

    from exo_bench.models.machine.numba_cache import KernelSourceLocator
    from exo_bench.models.machine.numba_runtime import ensure

    layer = ensure()
    key = caching.FunctionCache._index_key
    assert ensure() == layer
    impl = caching.CacheImpl if hasattr(caching, "CacheImpl") else caching._CacheImpl
    assert impl._locator_classes.count(KernelSourceLocator) == 1
    assert caching.FunctionCache._index_key is key and key.keyed_by_code
    wrapped = [c.cell_contents for c in key.__closure__ or ()]
    assert not any(getattr(w, "keyed_by_code", False) for w in wrapped)  # numba's own key inside, once
