"""The names a user gives (mechanisms, links, scenes): what a name may hold, and the one encoder that
turns a name into a file name.

A name is data. It may hold any printable character, the metacharacters of XML, LaTeX, C and Python
included: each generated format escapes it with its own encoder. What is refused here is what no
encoder can carry faithfully or what makes one name look like another:

* anything but a ``str`` (bytes, numbers, ``None``);
* the empty name, and a name that starts or ends with white space (``" a"`` prints as ``"a"``);
* lone surrogates (``"\\ud800"``): not encodable as UTF-8, so no file can hold them;
* control characters (Unicode category Cc: C0, DEL, C1 such as U+0085), line and paragraph
  separators (Zl, Zp: U+2028, U+2029) and format characters (Cf: the bidi overrides and isolates
  U+202A-U+202E and U+2066-U+2069, zero-width characters, U+FEFF), which reorder, hide or break
  the text a reader sees;
* names longer than :data:`MAX_NAME_LENGTH` characters.
"""

from __future__ import annotations

import re
import unicodedata
from typing import Any

#: The longest name accepted, in characters: a file name of its UTF-8 encoding (at most 4 bytes a
#: character) plus an extension stays under the 255 bytes most file systems allow.
MAX_NAME_LENGTH = 60

_REFUSED_CATEGORIES = {"Cc": "a control character", "Cf": "a format character", "Zl": "a line separator"}
_REFUSED_CATEGORIES["Zp"] = "a paragraph separator"
_REFUSED_CATEGORIES["Cs"] = "a lone surrogate (not encodable as UTF-8)"
_REFUSED_CATEGORIES["Co"] = "a private-use character"
_REFUSED_CATEGORIES["Cn"] = "an unassigned code point"


def name_problem(value: Any) -> str | None:
    """Why ``value`` is not an acceptable name, or ``None`` if it is (see the module docstring)."""
    if not isinstance(value, str):
        return f"expected a string, got {type(value).__name__} {value!r}"
    if not value:
        return "expected a non-empty name, got ''"
    if value != value.strip():
        return f"expected a name without leading or trailing white space, got {ascii(value)}"
    if len(value) > MAX_NAME_LENGTH:
        return f"expected at most {MAX_NAME_LENGTH} characters, got {len(value)}"
    for i, ch in enumerate(value):
        why = _REFUSED_CATEGORIES.get(unicodedata.category(ch))
        if why is not None:
            return f"expected printable characters only, got {why} U+{ord(ch):04X} at position {i} in {ascii(value)}"
    return None


def check_name(value: Any, what: str) -> str:
    """``value`` if it is an acceptable name, else ``ValueError("{what}: ...")``; ``what`` names the
    object and field, for example ``"exo5-3d: link 3: field 'name'"``."""
    why = name_problem(value)
    if why is not None:
        raise ValueError(f"{what}: {why}")
    return value


_UNSAFE_IN_FILE_NAME = re.compile(r"[^A-Za-z0-9_-]+")


def file_stem(name: str) -> str:
    """The file-name encoder: the stem of a file named after ``name``.

    ASCII letters, digits, ``_`` and ``-`` are kept, every other run of characters becomes one
    ``_``, and a leading ``-`` or ``.`` cannot occur (so the stem is never an option, a hidden file,
    ``.`` or ``..``, and holds no path separator). A name with nothing left becomes ``"unnamed"``.
    Two names may share a stem (``"a b"`` and ``"a_b"``): callers that write several files in one
    folder check their stems for collisions."""
    stem = _UNSAFE_IN_FILE_NAME.sub("_", name).lstrip("-")
    return stem if stem.strip("_") else "unnamed"
