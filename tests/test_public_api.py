"""The public API (issue 47): every name a user needs is importable from ``exo_bench`` itself, lazily, and the
README, the gallery and the docs' Python blocks import from nowhere else.

* each name of ``exo_bench.__all__`` imports and is the object it names (:data:`DEFINED_AS`: the name it
  is defined under, in the module the lazy table points at: the table names where it is defined, not a
  re-export);
* ``__all__``, the lazy table, ``__dir__``, the ``TYPE_CHECKING`` imports and docs/guide/public-api.md
  list the same names, and each call the page shows binds to the real signature;
* ``import exo_bench`` imports none of sympy, casadi, pinocchio or numba (a fresh interpreter);
* every ``import`` of the README's and the docs' Python blocks and of docs/examples/*.py that names
  exo_bench is ``import exo_bench`` or ``from exo_bench import NAME`` with NAME public.
"""

from __future__ import annotations

import ast
import importlib
import inspect
import re
import subprocess
import sys
import types
from pathlib import Path

import pytest

import exo_bench

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "guide" / "public-api.md"

#: Each public name and the name its object is defined under (``None``: a module). Where it lives is
#: exo_bench._LAZY's business alone; this says what it is.
DEFINED_AS: dict[str, str | None] = {
    "prepare": "prepare",
    "PreparedModel": "PreparedModel",
    "method_names": "method_names",
    "MethodSpec": "MethodSpec",
    "Mechanism": "Mechanism",
    "presets": None,
    "load_mechanism": "load_mechanism",
    "save_mechanism": "save_mechanism",
    "random_states": "random_states",
    "smooth_random_motion": "smooth_random_motion",
    "gait": "gait",
    "planar_gait": "planar_gait",
    "Motion": "Motion",
    "GaitParams": "GaitParams",
    "forces_at": "forces_at",
    "simulate": "simulate",
    "Simulation": "Simulation",
    "prescribed_controls": "prescribed_controls",
    "rod_spring_damper": "rod_spring_damper",
    "net_joint_loads": "net_joint_loads",
    "sagittal_moments": "sagittal_moments",
    "joint_torques": "joint_torques",
    "pinocchio_model": "build_model",
    "to_urdf": "to_urdf",
    "to_mjcf": "to_mjcf",
    "render_equations": "render",
    "write_equations": "write_equations",
    "casadi_functions": "casadi_functions",
    "load_step": "load",
    "step_violations": "violations",
    "SingularConfigurationError": "SingularConfigurationError",
    "MissingExtra": "MissingExtra",
    "ResourceLimit": "ResourceLimit",
    "BudgetExceeded": "BudgetExceeded",
    "CallTooLarge": "CallTooLarge",
    "PinocchioDataTooLarge": "PinocchioDataTooLarge",
    "MjcfTooDeep": "MjcfTooDeep",
}

#: The error classes and what a caller may catch them as.
ERRORS = {
    "SingularConfigurationError": ValueError,
    "MissingExtra": ValueError,
    "ResourceLimit": ValueError,
    "BudgetExceeded": ValueError,
    "CallTooLarge": MemoryError,
    "PinocchioDataTooLarge": MemoryError,
    "MjcfTooDeep": ValueError,
}

PUBLIC = [n for n in exo_bench.__all__ if n != "__version__"]


def test_all_lists_each_name_once_and_the_lazy_table_the_same_names():
    assert len(exo_bench.__all__) == len(set(exo_bench.__all__))
    assert "__version__" in exo_bench.__all__
    assert set(PUBLIC) == set(exo_bench._LAZY) == set(DEFINED_AS)
    assert set(exo_bench.__all__) <= set(dir(exo_bench))


@pytest.mark.parametrize("name", PUBLIC)
def test_a_public_name_imports_and_is_the_object_it_names(name):
    module, attr = exo_bench._LAZY[name]
    obj = getattr(exo_bench, name)
    namespace: dict = {}
    exec(f"from exo_bench import {name}", namespace)
    assert namespace[name] is obj
    if DEFINED_AS[name] is None:
        assert isinstance(obj, types.ModuleType) and obj.__name__ == module and attr is None
        return
    # defined there under that name: the table points at the definition, never at a re-export
    assert (obj.__module__, obj.__name__) == (module, DEFINED_AS[name])
    assert getattr(importlib.import_module(module), attr) is obj
    if name in ERRORS:
        assert isinstance(obj, type) and issubclass(obj, ERRORS[name])


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'simulation'"):
        exo_bench.simulation  # noqa: B018
    with pytest.raises(ImportError):
        exec("from exo_bench import random_state", {})


def test_the_type_checking_imports_are_the_lazy_table():
    """What type checkers and IDEs see (the ``if TYPE_CHECKING:`` imports) is what runs (``_LAZY``)."""
    tree = ast.parse(Path(exo_bench.__file__).read_text())
    block = next(node for node in tree.body if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING")
    seen: dict[str, tuple[str, str | None]] = {}
    for node in block.body:
        assert isinstance(node, ast.ImportFrom) and node.module, ast.unparse(node)
        for alias in node.names:
            name = alias.asname or alias.name
            target = (node.module, alias.name)
            if exo_bench._LAZY.get(name) == (f"{node.module}.{alias.name}", None):  # a module
                target = (f"{node.module}.{alias.name}", None)
            assert name not in seen, name
            seen[name] = target
    assert seen == exo_bench._LAZY


def test_importing_the_package_imports_no_heavy_dependency():
    """``import exo_bench`` (and listing its names) loads none of sympy, casadi, pinocchio or numba."""
    code = (
        "import sys, exo_bench; dir(exo_bench); exo_bench.__all__; "
        "print(sorted(m for m in ('sympy', 'casadi', 'pinocchio', 'numba') if m in sys.modules))"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"
    # the check can fail: a public name that needs pinocchio imports it
    code = "import sys, exo_bench; exo_bench.joint_torques; print('pinocchio' in sys.modules)"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.stdout.strip() == "True", r.stderr


# ------------------------------------------------------------------ the page that lists the names
def _page_rows() -> dict[str, str]:
    """``name -> what`` of the page's tables (first column a name in backquotes)."""
    rows = re.findall(r"^\| `(\w+)` \| (.*) \|$", PAGE.read_text(), re.M)
    names = [n for n, _ in rows]
    assert len(names) == len(set(names)), "a name listed twice"
    return dict(rows)


def test_the_page_lists_exactly_the_public_names():
    assert set(_page_rows()) == set(PUBLIC)
    assert "everything else is internal" in PAGE.read_text().lower()


def test_each_call_the_page_shows_binds_to_the_signature():
    """A call shown as ``name(a, b, key=v)`` passes its arguments as the function takes them."""
    shown = 0
    for name, what in _page_rows().items():
        m = re.search(rf"`({name}\(.*?\))`", what)
        if m is None:
            continue
        call = ast.parse(m.group(1), mode="eval").body
        assert isinstance(call, ast.Call)
        args = [None for a in call.args]
        kwargs = {k.arg: None for k in call.keywords if k.arg is not None}
        inspect.signature(getattr(exo_bench, name)).bind(*args, **kwargs)
        shown += 1
    assert shown >= 20


# ------------------------------------------------------------------ what the README and the docs import
def _python_sources() -> list[tuple[str, str]]:
    """``(where, code)`` of every docs/examples/*.py and every ```python block of README.md and docs/."""
    out = [(str(p.relative_to(ROOT)), p.read_text()) for p in sorted((ROOT / "docs" / "examples").glob("*.py"))]
    pages = [ROOT / "README.md"] + sorted(
        p for p in (ROOT / "docs").rglob("*.md") if not {"_build", "gallery"} & set(p.relative_to(ROOT).parts)
    )
    for page in pages:
        for k, block in enumerate(re.findall(r"```python\n(.*?)\n```", page.read_text(), re.S)):
            out.append((f"{page.relative_to(ROOT)}#{k}", block))
    return out


def internal_imports(code: str) -> list[str]:
    """The imports of ``code`` that reach below ``exo_bench`` or name what it does not export."""
    bad = []
    for node in ast.walk(ast.parse(code)):
        if isinstance(node, ast.Import):
            bad += [a.name for a in node.names if a.name.startswith("exo_bench.")]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "exo_bench":
            if node.module != "exo_bench" or node.level:
                bad.append(f"from {node.module} import ...")
            else:
                bad += [f"from exo_bench import {a.name}" for a in node.names if a.name not in exo_bench.__all__]
    return bad


def test_the_checker_finds_internal_imports():
    code = (
        "import exo_bench\nfrom exo_bench import prepare\ndef f():\n    from exo_bench.models.gait.motion import gait\n"
    )
    assert internal_imports(code) == ["from exo_bench.models.gait.motion import ..."]
    assert internal_imports("import exo_bench.models.engines.urdf as u\nfrom exo_bench import _LAZY") == [
        "exo_bench.models.engines.urdf",
        "from exo_bench import _LAZY",
    ]


SOURCES = _python_sources()


def test_the_readme_and_the_gallery_are_checked():
    where = [w for w, _ in SOURCES]
    assert any(w.startswith("README.md#") for w in where)
    assert sum(w.startswith("docs/examples/plot_") for w in where) >= 7


@pytest.mark.parametrize("where,code", SOURCES, ids=[w for w, _ in SOURCES])
def test_examples_import_only_the_public_api(where, code):
    assert internal_imports(code) == [], f"{where} imports internals"
