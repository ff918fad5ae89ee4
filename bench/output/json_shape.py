"""The shape of every JSON file the suite reads back (a reports folder's ``runs.json``, a sweep's
checkpoints), checked before it is used and before any work: one ValueError line naming the file
and the field, never an AttributeError deep in a run after all its work.

A shape is a small description of the expected value (:func:`problem`):

* a type or a tuple of types: ``str``, ``(int, float)``, ``NUMBER`` (``bool`` is never a number),
  ``type(None)`` for null;
* ``[shape]``: a list of items of that shape;
* ``{"key": shape, "key?": shape}``: an object with those fields (``?``: may be absent; other keys
  are allowed);
* ``Values(shape)``: an object of any keys whose values have that shape;
* ``OrNull(shape)``: that shape or null.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

NUMBER = (int, float)
NULL = type(None)


@dataclass(frozen=True)
class Values:
    """An object of any keys (strings) whose values have ``shape``."""

    shape: Any


@dataclass(frozen=True)
class OrNull:
    """``shape`` or null."""

    shape: Any


_NAMES = {str: "a string", int: "an integer", float: "a number", bool: "true or false", NULL: "null"}
_JSON_TYPES = {dict: "an object", list: "a list", str: "a string", bool: "a boolean", NULL: "null"}


def _got(value: Any) -> str:
    if isinstance(value, bool):
        return f"a boolean ({value})"
    if isinstance(value, (int, float)):
        return f"a number ({value!r})"
    return _JSON_TYPES.get(type(value), type(value).__name__)


def _expected(shape: Any) -> str:
    if isinstance(shape, OrNull):
        return f"{_expected(shape.shape)} or null"
    if isinstance(shape, list):
        return "a list"
    if isinstance(shape, (dict, Values)):
        return "an object"
    if shape == NUMBER:
        return "a number"
    kinds = shape if isinstance(shape, tuple) else (shape,)
    return " or ".join(_NAMES.get(k, k.__name__) for k in kinds)


def _is(value: Any, kinds: type | tuple) -> bool:
    kinds = kinds if isinstance(kinds, tuple) else (kinds,)
    if isinstance(value, bool):
        return bool in kinds
    return isinstance(value, kinds)


def problem(value: Any, shape: Any, where: str = "") -> str | None:
    """What is wrong with ``value`` against ``shape`` (``field 'runs.r1.command': expected a string,
    got a list``), or None."""
    here = f"field {where!r}" if where else "the top level"
    if isinstance(shape, OrNull):
        p = None if value is None else problem(value, shape.shape, where)
        head = f"{here}: expected "
        if p and p.startswith(head) and ", got " in p:  # this value's own kind is wrong, not a field's in it
            kind, got = p[len(head) :].split(", got ", 1)
            return f"{head}{kind} or null, got {got}"
        return p
    if isinstance(shape, list):
        if not isinstance(value, list):
            return f"{here}: expected a list, got {_got(value)}"
        for i, item in enumerate(value):
            p = problem(item, shape[0], f"{where}[{i}]")
            if p:
                return p
        return None
    if isinstance(shape, (dict, Values)):
        if not isinstance(value, dict):
            return f"{here}: expected an object, got {_got(value)}"
        if isinstance(shape, Values):
            fields = [(k, shape.shape, False) for k in value]
        else:
            fields = [(k.rstrip("?"), s, k.endswith("?")) for k, s in shape.items()]
        for key, sub, optional in fields:
            inner = f"{where}.{key}" if where else str(key)
            if key not in value:
                if optional:
                    continue
                return f"field {inner!r}: missing (expected {_expected(sub)})"
            p = problem(value[key], sub, inner)
            if p:
                return p
        return None
    if not _is(value, shape):
        return f"{here}: expected {_expected(shape)}, got {_got(value)}"
    return None


def check(value: Any, shape: Any, source: str, advice: str = "") -> Any:
    """``value`` when it has ``shape``; otherwise one ValueError line naming ``source`` (the file)
    and the field, and ``advice`` (what to do about it)."""
    p = problem(value, shape)
    if p:
        raise ValueError(f"{source}: {p}" + (f"; {advice}" if advice else ""))
    return value


def read_checked(path: str | Path, shape: Any, advice: str = "") -> Any:
    """The JSON of the regular file ``path``, checked against ``shape``; one ValueError line naming
    the file when it cannot be read, is not JSON, or has another shape."""
    p = Path(path)
    try:
        if not p.is_file():  # a FIFO would block, a device never end
            raise ValueError(f"{p}: expected a JSON file, got something else there (a folder, a FIFO, a device)")
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(
            f"{p}: cannot be read ({getattr(e, 'strerror', None) or e})" + (f"; {advice}" if advice else "")
        ) from None
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as e:
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ValueError(f"{p}: not valid JSON ({why})" + (f"; {advice}" if advice else "")) from None
    return check(data, shape, str(p), advice)


# ------------------------------------------------------------------------------ runs.json
#: A reports folder's ``runs.json`` (bench/output/publish.py): every field the publisher reads.
MANIFEST = {
    "format": int,
    "runs": Values({"command?": str, "status?": str, "finished?": str}),
    "scenes?": Values({"run": str, "rows": [[(str, int, float, NULL)]]}),
    "files?": Values({"run?": str}),
}
MANIFEST_ADVICE = "fix it or move it away (it lists which run made each report of the folder)"


def check_manifest(data: Any, path: str | Path) -> dict:
    """``runs.json``'s ``data`` (read from ``path``) when it has the shape of format 1, else one
    ValueError line naming the file and the field."""
    return check(data, MANIFEST, str(path), MANIFEST_ADVICE)


def check_manifest_file(folder: str | Path) -> None:
    """Before any work: the ``runs.json`` of the reports folder ``folder``, if there is one of format
    1, has the shape the publisher reads (a file of another format or not JSON is left to the
    publisher, which says so and starts a new one)."""
    p = Path(folder) / "runs.json"
    try:
        if not p.is_file():
            return
        data = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return
    if isinstance(data, dict) and data.get("format") == 1:
        check_manifest(data, p)
