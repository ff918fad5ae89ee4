"""Reading what users give us: a mechanism (a preset's name or a JSON file), JSON and TOML files.

One reader for every file the suite takes from a user, so that every I/O and decoding error
names the file and says what was expected: a missing file, a folder, an unreadable or binary
file (not UTF-8) and invalid JSON or TOML each give one ``ValueError`` line.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

from exo_bench.models.mechanism import Mechanism


def read_text(path: str | Path, what: str) -> str:
    """The UTF-8 text of ``path``; ``what`` names the file's role in messages (``"states 'x.json'"``)."""
    p = Path(path)
    if not p.exists():
        raise ValueError(f"{what}: no such file")
    if p.is_dir():
        raise ValueError(f"{what}: expected a file, got a folder")
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ValueError(f"{what}: cannot read: {e.strerror}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(f"{what}: expected UTF-8 text, got bytes that are not (byte {e.start}: {data[e.start:e.start + 1]!r}); "
                         "is this a binary file?") from None


def read_json(path: str | Path, what: str) -> Any:
    try:
        return json.loads(read_text(path, what))
    except json.JSONDecodeError as e:
        raise ValueError(f"{what}: invalid JSON: {e}") from None


def read_toml(path: str | Path, what: str) -> dict:
    try:
        return tomllib.loads(read_text(path, what))
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{what}: invalid TOML: {e}") from None


def load_mechanism(spec: str | Path) -> Mechanism:
    """A preset name (see ``exo-bench presets``) or the path of a JSON file."""
    from exo_bench.models.presets import PRESETS

    key = str(spec)
    if key in PRESETS:
        return PRESETS[key]()
    if not Path(spec).exists():
        raise ValueError(f"mechanism {key!r}: not a preset ({', '.join(sorted(PRESETS))}) and no such file")
    return Mechanism.from_dict(read_json(spec, f"mechanism {key!r}"), source=str(spec))


def save_mechanism(mech: Mechanism, path: str | Path) -> None:
    Path(path).write_text(mech.to_json() + "\n")
