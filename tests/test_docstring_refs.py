"""Docstring cross-references name things that import (issue 21): every ``:mod:``, ``:func:``,
``:class:``, ``:data:``, ``:meth:``, ``:attr:`` or ``:exc:`` role in the library whose target is a
dotted path resolves (a module, then attributes); a bare name refers to its own module and is not
checked here. Paths of the old layout (``bench.reporting``, ``matrix_method.numeric``) fail."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ROLE = re.compile(r":(?:mod|func|class|data|meth|attr|exc):`~?([A-Za-z_][\w.]*\.[\w.]*\w)`")
LIBRARY = ("exo_bench", "models", "matrix_method", "lagrange", "bench")


_MISSING = object()


def _resolves(target: str) -> bool:
    parts = target.split(".")
    if _get(parts) is not _MISSING:
        return True
    # a method or attribute of a class set in __init__ (instance attributes do not getattr)
    return len(parts) > 2 and isinstance(_get(parts[:-1]), type)


def _get(parts: list[str]):
    """The object at the dotted path ``parts`` (a module, then attributes), or _MISSING."""
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        try:
            for name in parts[i:]:
                obj = getattr(obj, name)
        except AttributeError:
            return _MISSING
        return obj
    return _MISSING


def _module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("").parts
    rel = rel[:-1] if rel[-1] == "__init__" else rel
    return ".".join(rel) if rel[0] == "exo_bench" else ".".join(("exo_bench",) + rel)


def test_every_dotted_cross_reference_imports():
    bad = []
    for top in LIBRARY:
        for path in sorted((ROOT / top).rglob("*.py")):
            if ".venv" in path.parts or path.name == "__main__.py":
                continue
            module = importlib.import_module(_module_name(path))
            for m in ROLE.finditer(path.read_text()):
                target = m.group(1)
                first = target.split(".")[0]
                if first == "exo_bench":
                    ok = _resolves(target)
                elif hasattr(module, first) and not isinstance(getattr(module, first), type(importlib)):
                    ok = _resolves(f"{module.__name__}.{target}")  # a class or function of this module
                else:
                    try:  # another library (fractions, dask's distributed)
                        importlib.import_module(first)
                        ok = _resolves(target) and not first.startswith(
                            ("bench", "models", "matrix_method", "lagrange")
                        )
                    except ImportError:
                        ok = False
                if not ok:
                    bad.append(f"{path.relative_to(ROOT)}: {target}")
    assert not bad, "\n".join(bad)
