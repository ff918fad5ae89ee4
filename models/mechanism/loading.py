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

from exo_bench.models.mechanism.mechanism import Mechanism  # noqa: F401 - loads: the JSON reader
from exo_bench.models.states.validation import DuplicateKey, loads


#: Peak memory of reading a JSON file of numbers, per byte of text: measured 3.3 (200,000 samples
#: of exo5-3d states, 181 MB: the text, Python's lists and floats, the float arrays), rounded up.
READ_BYTES_PER_BYTE = 4


def regular_file(path: str | Path, what: str) -> Path:
    """``path`` as a :class:`Path` when it names an existing regular file; otherwise one
    ValueError line (no such file, a folder, a device/FIFO/socket, an unusable path)."""
    p = Path(path)
    try:
        exists, is_dir, is_file = p.exists(), p.is_dir(), p.is_file()
    except (OSError, ValueError) as e:  # a NUL character, a name too long
        raise ValueError(f"{what}: not a usable path ({getattr(e, 'strerror', None) or e})") from None
    if not exists:
        raise ValueError(f"{what}: no such file")
    if is_dir:
        raise ValueError(f"{what}: expected a file, got a folder")
    if not is_file:
        raise ValueError(f"{what}: expected a regular file, got a device, FIFO or socket")
    return p


def read_text(path: str | Path, what: str) -> str:
    """The UTF-8 text of ``path``; ``what`` names the file's role in messages (``"states 'x.json'"``).

    Only regular files are read (a FIFO or a device such as /dev/zero would block or never end),
    and only when reading fits in the memory a run may use (:func:`exo_bench.models.machine.memory.usable_memory`)."""
    from exo_bench.models.machine.memory import usable_memory

    p = regular_file(path, what)
    size = p.stat().st_size
    limit = usable_memory()
    if limit is not None and size * READ_BYTES_PER_BYTE > limit:
        raise ValueError(
            f"{what}: {size / 1e9:.1f} GB of text would need about {size * READ_BYTES_PER_BYTE / 1e9:.0f} GB "
            f"to read, more than the {limit / 1e9:.1f} GB a run may use; split it, or give states as a "
            ".npz file"
        )
    try:
        data = p.read_bytes()
    except OSError as e:
        raise ValueError(f"{what}: cannot read: {e.strerror}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ValueError(
            f"{what}: expected UTF-8 text, got bytes that are not (byte {e.start}: {data[e.start : e.start + 1]!r}); "
            "is this a binary file?"
        ) from None


def read_json(path: str | Path, what: str) -> Any:
    text = read_text(path, what)
    try:
        return loads(text)
    except DuplicateKey as e:
        raise ValueError(f"{what}: invalid JSON: {e}") from None
    except json.JSONDecodeError as e:
        raise ValueError(f"{what}: invalid JSON: {e}") from None
    except RecursionError:
        raise ValueError(
            f"{what}: JSON nested too deeply to read (more than Python's recursion limit of about 1000 levels)"
        ) from None


def read_toml(path: str | Path, what: str) -> dict:
    text = read_text(path, what)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{what}: invalid TOML: {e}") from None
    except RecursionError:
        raise ValueError(f"{what}: TOML nested too deeply to read") from None


def load_mechanism(spec: str | Path) -> Mechanism:
    """A preset name (see ``exo-bench presets``) or the path of a JSON file."""
    from exo_bench.models.mechanism.presets import PRESETS

    key = str(spec)
    if key in PRESETS:
        return PRESETS[key]()
    try:
        exists = Path(spec).exists()
    except (OSError, ValueError) as e:  # a NUL character, a name too long
        raise ValueError(
            f"mechanism {key!r}: not a preset and not a usable path ({getattr(e, 'strerror', None) or e})"
        ) from None
    if not exists:
        raise ValueError(f"mechanism {key!r}: not a preset ({', '.join(sorted(PRESETS))}) and no such file")
    return Mechanism.from_dict(read_json(spec, f"mechanism {key!r}"), source=str(spec))


def save_mechanism(mech: Mechanism, path: str | Path) -> None:
    """``mech`` as JSON to ``path``, whole or not at all, never through a symlink planted there
    (:func:`exo_bench.models.files.atomic_files.atomic_write`)."""
    from exo_bench.models.files.atomic_files import atomic_write

    atomic_write(path, mech.to_json() + "\n")
