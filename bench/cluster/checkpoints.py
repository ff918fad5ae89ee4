"""Checkpoints of a sweep: the code a sweep measures (:func:`code_key`), a folder per code, a file per
finished row (written atomically), so that a sweep run again after an interruption runs only the missing rows;
and the stability study's checkpointed parts as tagged JSON (:func:`encode`, :func:`decode`): nothing read
from disk is ever unpickled."""

from __future__ import annotations

import base64
import dataclasses
import math
import subprocess
import types
import typing
from collections.abc import Callable
from functools import cache, lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from exo_bench.bench.perf import rows as _rows
from exo_bench.bench.output.json_shape import OrNull, read_checked
from exo_bench.bench.output.provenance import REPO


#: Row statuses whose record is final and checkpointed: pytest ran the row to its end (its tests
#: passed or failed), or the row exceeded its budget (running it again would exceed it again).
FINAL = ("ok", "failed", "over budget")


# ----------------------------------------------------------------------------- code identity
def code_key(repo: Path = REPO) -> str:
    """The code a sweep measures: the commit, plus a hash of the uncommitted changes to tracked
    files if any (generated reports and README.md excepted); the package version outside git."""
    import hashlib

    try:
        head = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=10)
        if head.returncode == 0 and head.stdout.strip():
            diff = subprocess.run(
                ["git", "-C", str(repo), "diff", "HEAD", "--", ".", ":!reports", ":!README.md"],
                capture_output=True,
                timeout=30,
            ).stdout
            return head.stdout.strip()[:12] + (f"-dirty-{hashlib.sha256(diff).hexdigest()[:8]}" if diff else "")
    except (OSError, subprocess.SubprocessError):
        pass
    from importlib import metadata

    try:
        return "v" + metadata.version("exo-bench")
    except metadata.PackageNotFoundError:
        return "unknown"


def checkpoint_dir(base: Path, code: str) -> Path:
    """Checkpoints of the rows measured with code ``code`` (:func:`code_key`)."""
    return Path(base) / code


#: The checkpoint folder's name inside a reports folder (hidden: never a report, never published;
#: .gitignore names it wherever it is).
CHECKPOINTS = ".exo-bench-sweep"


def default_checkpoints(reports: Path) -> Path:
    """The checkpoint folder of a reports folder: ``.exo-bench-sweep`` inside it. Nothing is written
    outside the folder a user names (issue 38: it was beside it, ``X/../.exo-bench-sweep``, so
    ``--reports /tmp/x`` wrote into /tmp and ``--reports ~/r`` into the home folder). A hidden folder
    is no report: the publisher and ``runs.json`` skip names starting with a dot."""
    return Path(reports).resolve() / CHECKPOINTS


#: A row's checkpoint (:func:`exo_bench.bench.cluster.tasks.run_row`'s record): every field that
#: :func:`exo_bench.bench.perf.rows.merge` and the sweep read (bench/output/json_shape.py).
_SKIP = {"nodeid": str, "reason?": (str, type(None))}
ROW_SHAPE = {
    "key": str,
    "status": str,
    "reason?": (str, type(None)),
    "host?": (str, type(None)),
    "cpu?": (str, type(None)),
    "seconds?": (int, float),
    "nodeids?": [str],
    "benchmark_json?": OrNull({"benchmarks?": [{"fullname": str, "extra_info?": dict}]}),
    "skips?": [_SKIP],
    "inherited?": [_SKIP],
    "machine_info?": (dict, type(None)),
}
ADVICE = "remove the file to measure the row again"


def load_checkpoint(folder: Path, key: str) -> dict | None:
    """The record checkpointed for the row ``key`` in ``folder``, or None when there is none (or one
    of another row, or not final). A file that is there but is not a row's record (not JSON, not an
    object, a field of another type) is one ValueError line naming the file and the field, before
    any work (the sweep reads every checkpoint first)."""
    p = folder / f"{_rows.safe_name(key)}.json"
    if not p.exists() and not p.is_symlink():
        return None
    rec = read_checked(p, ROW_SHAPE, ADVICE)
    return rec if rec["key"] == key and rec["status"] in FINAL else None


# ----------------------------------------------------------------------------- the stability study's parts
def part_file(folder: Path, tag: str) -> Path:
    """The checkpoint of one part of the stability study (JSON: bench/cluster/checkpoints.py)."""
    return Path(folder) / f"{tag}.json"


def load_part(folder: Path, tag: str, result_type: str):
    """``(result, warnings)`` of the part ``tag`` checkpointed in ``folder``, or None when there is
    none; a file that is not such a part is one ValueError line naming it and the field. Never a
    pickle: a ``.pickle`` file there (from an older version, or planted) is never read."""

    p = part_file(folder, tag)
    if not p.exists() and not p.is_symlink():
        return None
    return read_part(read_checked(p, dict, "remove the file to run the part again"), tag, str(p), result_type)


def save_part(folder: Path, tag: str, part) -> Path:
    """Write the part ``(result, warnings)`` as JSON, atomically."""
    from exo_bench.models.files import atomic_write

    return atomic_write(part_file(folder, tag), part_text(tag, part))


# The stability study's checkpoints as JSON: nothing read from disk is ever unpickled.

#: The tag of a part file (its format); a file with another is refused.
FORMAT = "exo-bench stability checkpoint 1"
#: Fields not kept (callables): ``class name -> field names``, read back as None.
DROPPED = {"Simulation": ("solution",)}


@lru_cache(maxsize=1)
def registry() -> dict[str, type]:
    """The dataclasses a checkpoint may hold, by class name."""
    from exo_bench.bench.studies.stability import cases, evaluation, forward_evaluation
    from exo_bench.bench.studies.stability import forward_round_trip
    from exo_bench.models.simulation.forward_dynamics import Simulation

    classes = (
        cases.Profile,
        cases.Case,
        evaluation.MethodRow,
        evaluation.CaseResult,
        evaluation.FamilyResult,
        forward_evaluation.ForwardResults,
        forward_evaluation.TermsRow,
        forward_evaluation.SingularDemo,
        forward_round_trip.RoundTrip,
        forward_evaluation.EnergyRun,
        forward_evaluation.StiffRun,
        Simulation,
    )
    return {c.__name__: c for c in classes}


# ------------------------------------------------------------------------------ encoding
def encode(value: Any, where: str = "value") -> Any:
    """``value`` as JSON-able data (tagged: ``$tuple``, ``$dict``, ``$float``, ``$array``,
    ``$mechanism``, ``$dataclass``); a ValueError naming ``where`` for anything else."""
    from exo_bench.models.mechanism.mechanism import Mechanism

    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        x = float(value)
        return x if math.isfinite(x) else {"$float": repr(x)}
    if isinstance(value, list):
        return [encode(v, f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, tuple):
        return {"$tuple": [encode(v, f"{where}[{i}]") for i, v in enumerate(value)]}
    if isinstance(value, dict):
        return {"$dict": [[encode(k, f"{where} key"), encode(v, f"{where}[{k!r}]")] for k, v in value.items()]}
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biufc":
            raise ValueError(f"{where}: an array of {value.dtype} cannot be checkpointed (numbers only)")
        a = np.ascontiguousarray(value)
        return {"$array": [a.dtype.str, list(a.shape), base64.b64encode(a.tobytes()).decode("ascii")]}
    if isinstance(value, Mechanism):
        return {"$mechanism": value.to_dict()}
    name = type(value).__name__
    if dataclasses.is_dataclass(value) and registry().get(name) is type(value):
        dropped = DROPPED.get(name, ())
        return {
            "$dataclass": name,
            "fields": {
                f.name: None if f.name in dropped else encode(getattr(value, f.name), f"{where}.{f.name}")
                for f in dataclasses.fields(value)
                if f.init
            },
        }
    raise ValueError(f"{where}: a {type(value).__qualname__} cannot be checkpointed as JSON")


# ------------------------------------------------------------------------------ decoding
_TAGS = ("$tuple", "$dict", "$float", "$array", "$mechanism", "$dataclass")


def decode(data: Any, where: str = "value") -> Any:
    """The value :func:`encode` made ``data`` from; a ValueError naming the field ``where`` when
    ``data`` is anything else."""
    if data is None or isinstance(data, (bool, int, float, str)):
        return data
    if isinstance(data, list):
        return [decode(v, f"{where}[{i}]") for i, v in enumerate(data)]
    if not isinstance(data, dict):
        raise ValueError(f"field {where!r}: unexpected {type(data).__name__}")
    tag = next((t for t in _TAGS if t in data), None)
    if tag is None or set(data) - {tag, "fields"} or ("fields" in data) != (tag == "$dataclass"):
        raise ValueError(f"field {where!r}: expected a tagged value ({', '.join(_TAGS)}), got keys {sorted(data)}")
    body = data[tag]
    if tag == "$tuple":
        return tuple(decode(_list(body, where), where))
    if tag == "$dict":
        pairs = _list(body, where)
        if not all(isinstance(p, list) and len(p) == 2 for p in pairs):
            raise ValueError(f"field {where!r}: expected [key, value] pairs")
        out = {}
        for k, v in pairs:
            key = decode(k, f"{where} key")
            try:
                out[key] = decode(v, f"{where}[{key!r}]")
            except TypeError:  # an unhashable key
                raise ValueError(f"field {where!r}: a key that is a {type(key).__name__}") from None
        return out
    if tag == "$float":
        if body not in ("nan", "inf", "-inf"):
            raise ValueError(f"field {where!r}: expected 'nan', 'inf' or '-inf', got {body!r}")
        return float(body)
    if tag == "$array":
        return _array(body, where)
    if tag == "$mechanism":
        from exo_bench.models.mechanism.mechanism import Mechanism

        return Mechanism.from_dict(body, source=f"field {where!r}")
    return _dataclass(body, data["fields"], where)


def _list(body: Any, where: str) -> list:
    if not isinstance(body, list):
        raise ValueError(f"field {where!r}: expected a list, got {type(body).__name__}")
    return body


def _array(body: Any, where: str) -> np.ndarray:
    try:
        dtype_str, shape, text = body
        dtype = np.dtype(dtype_str)
        if dtype.kind not in "biufc" or not all(isinstance(n, int) and n >= 0 for n in shape):
            raise ValueError
        raw = base64.b64decode(text.encode("ascii"), validate=True)
        return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()
    except (ValueError, TypeError, AttributeError):
        raise ValueError(f"field {where!r}: not an array of numbers [dtype, shape, base64 bytes]") from None


def _dataclass(name: Any, fields: Any, where: str) -> Any:
    cls = registry().get(name) if isinstance(name, str) else None
    if cls is None:
        raise ValueError(f"field {where!r}: {name!r} is not a result type a checkpoint may hold")
    declared = {f.name for f in dataclasses.fields(cls) if f.init}
    if not isinstance(fields, dict) or set(fields) != declared:
        got = sorted(fields) if isinstance(fields, dict) else type(fields).__name__
        raise ValueError(f"field {where!r}: a {name} has the fields {sorted(declared)}, got {got}")
    hints = _hints(cls)
    values = {}
    for k, v in fields.items():
        value = decode(v, f"{where}.{k}")
        if k in hints and not _fits(value, hints[k]):
            want = getattr(hints[k], "__name__", None) or str(hints[k]).replace("typing.", "")
            raise ValueError(f"field {where + '.' + k!r}: expected {want}, got {type(value).__name__}")
        values[k] = value
    return cls(**values)


@cache
def _hints(cls: type) -> dict[str, Any]:
    try:
        return typing.get_type_hints(cls)
    except Exception:  # noqa: BLE001 - an annotation that does not resolve here: its fields go unchecked
        return {}


def _fits(value: Any, hint: Any) -> bool:
    """Whether ``value`` has the type ``hint`` (the hints the result types use)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is Any or hint is object:
        return True
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, a) for a in args)
    if hint is type(None):
        return value is None
    if hint is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if hint is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if origin is Callable or hint is Callable:
        return value is None  # never kept (DROPPED)
    if origin in (list, tuple, dict):
        if not isinstance(value, origin):
            return False
        if origin is dict:
            return all(_fits(k, args[0]) and _fits(v, args[1]) for k, v in value.items()) if args else True
        if origin is tuple and args and args[-1] is not Ellipsis:
            return len(value) == len(args) and all(_fits(v, a) for v, a in zip(value, args))
        return all(_fits(v, args[0]) for v in value) if args else True
    if isinstance(hint, type):
        return isinstance(value, hint)
    return True  # a hint this check does not know: the dataclass's own checks hold


# ------------------------------------------------------------------------------ a part's file
def part_text(key: str, part: Any) -> str:
    """The JSON of one checkpointed part ``(result, warnings)`` under ``key``."""
    import json

    return json.dumps({"format": FORMAT, "key": key, "value": encode(part, "part")}, allow_nan=False)


def read_part(data: Any, key: str, source: str, result_type: str) -> tuple[Any, list]:
    """``(result, warnings)`` from the JSON ``data`` of a part file (``source``: the file), checked:
    its format and key, a ``result_type`` result and ``[category, message]`` warnings."""
    from exo_bench.bench.output.json_shape import check

    advice = "remove the file to run the part again"
    check(data, {"format": str, "key": str, "value": dict}, source, advice)
    for field, want in (("format", FORMAT), ("key", key)):
        if data[field] != want:
            raise ValueError(f"{source}: field {field!r}: expected {want!r}, got {data[field]!r}; {advice}")
    try:
        part = decode(data["value"], "value")
        if not (isinstance(part, tuple) and len(part) == 2 and type(part[0]).__name__ == result_type):
            raise ValueError(f"field 'value': expected ({result_type}, warnings)")
        if not isinstance(part[1], list) or not all(
            isinstance(w, tuple) and len(w) == 2 and all(isinstance(s, str) for s in w) for w in part[1]
        ):
            raise ValueError("field 'value[1]': expected a list of (category, message) pairs")
    except ValueError as e:
        raise ValueError(f"{source}: {e}; {advice}") from None
    return part
