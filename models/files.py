"""What the package writes: the one encoder per output format for every name a user gives, and the one
atomic writer that never follows a link and never leaves a file half-written. Anything that turns a user's
string into bytes on disk belongs here.

**Names and encoders.** Every string a user names (a mechanism,
a link, a scene) that reaches a generated file goes through the function here for that file's language, and nowhere else.

A name is data, never code. What a name may hold is decided once, below
(:func:`~exo_bench.models.files.check_name`): printable characters, the metacharacters of every
format included. Each encoder below takes such a name and writes it so that the format reads it back
as the same text, with no way to end the element, comment, string or group it sits in:

* XML (MJCF, URDF): :func:`xml_attr` (a quoted attribute value), :func:`xml_comment` (comment text);
* LaTeX: :func:`latex_text` (text mode: every special character as its text command);
* Markdown: :func:`markdown_text` (prose, headings, table cells), :func:`markdown_code` (a code span);
* C: :func:`c_comment` (inside ``/* */``), :func:`c_identifier` (function prefix and file stem);
* Python: :func:`python_string` (a literal), :func:`python_docstring` (text inside ``\"\"\"``),
  :func:`python_module_name` (the module and its file stem).

File names: :func:`exo_bench.models.files.file_stem`. Identifiers and module names are built on it,
so they are ASCII, and they never shadow what the generated code imports: a C prefix is never a
standard header's name (``math`` -> ``m_math``, not ``math.h``), a Python module never a standard
module's or ``numpy`` (``numpy`` -> ``m_numpy``, not ``numpy.py``, which would import itself).

The names a user gives (mechanisms, links, scenes): what a name may hold, and the one encoder that
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

The one writer of every file the package writes: atomic, never through a link, never half-written.

The command line's ``-o`` and ``--reports`` (bench/output/files.py ``write_output``, the publisher's
``move_into``), the reports, figures, recordings and checkpoints (bench/output/provenance.py
``atomic_write``/``atomic_path``, which call this), the stored steps and strides, the library's
:func:`exo_bench.models.mechanism.presets.save_mechanism` and the CasADi functions' ``save`` all write here
(it lives in models so that every layer can use it; layers only go down).

* :func:`output_target`: a file is written only where there is nothing or a regular file: a symlink
  (to anything), a FIFO, a device, a socket or a folder is refused in one line (a ValueError), and
  so is the caller's own input.
* :func:`replace_atomically`: the data go to a new temporary file in the same folder (``O_EXCL |
  O_NOFOLLOW``, relative to the folder's descriptor), renamed over the name when complete: never
  through a link planted there, never half-written (an error or Ctrl-C removes the temporary); a
  replaced file keeps its mode, and every OSError names the file.
* :func:`atomic_write` (bytes or text) and :func:`atomic_path` (for a writer that needs a file name:
  numpy's savez, CasADi's ``Function.save``, rerun's file sink).
"""

from __future__ import annotations

import errno
import json
import keyword
import os
import re
import stat
import sys
import unicodedata
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
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


# ------------------------------------------------------------------------------------------- XML
_XML_ATTR = {"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&apos;"}


def xml_attr(value: str) -> str:
    """``value`` as a double-quoted XML attribute value, quotes included: ``& < > " '`` as entities."""
    return '"' + "".join(_XML_ATTR.get(ch, ch) for ch in value) + '"'


def xml_comment(value: str) -> str:
    """``value`` as text inside an XML comment: its JSON string literal (quotes included), with
    every ``-`` that another ``-`` follows written ``\\u002d``. A comment has no character
    references and may neither hold ``--`` nor end with ``-``; this text does neither, and
    ``json.loads`` of it gives ``value`` back."""
    return re.sub(r"-(?=-)", r"\\u002d", json.dumps(value, ensure_ascii=False))


# ----------------------------------------------------------------------------------------- LaTeX
#: Every character with a meaning in LaTeX's text mode, and the text it is written as.
LATEX_ESCAPES = {
    "\\": r"\textbackslash{}",
    "{": r"\{",
    "}": r"\}",
    "$": r"\$",
    "&": r"\&",
    "%": r"\%",
    "#": r"\#",
    "_": r"\_",
    "^": r"\textasciicircum{}",
    "~": r"\textasciitilde{}",
    "<": r"\textless{}",
    ">": r"\textgreater{}",
    "|": r"\textbar{}",
    "-": "-{}",  # no en or em dash ligature: "--" stays two hyphens
}


def latex_text(value: str) -> str:
    """``value`` as LaTeX text-mode material: every special character as its escape
    (:data:`LATEX_ESCAPES`), so no control sequence, group, math shift, comment or alignment tab
    comes from it. Other characters are written as they are (UTF-8): pdfLaTeX sets accented Latin
    letters, and refuses, with an error and nothing run, a character it has no glyph for (CJK, emoji),
    which XeLaTeX and LuaLaTeX set from the font."""
    return "".join(LATEX_ESCAPES.get(ch, ch) for ch in value)


# -------------------------------------------------------------------------------------- Markdown
_MD_PUNCTUATION = re.compile(r"([!-/:-@\[-`{-~])")


def markdown_text(value: str) -> str:
    """``value`` as Markdown text (prose, a heading, a table cell): every ASCII punctuation
    character backslash-escaped, so it renders as itself and opens no link, emphasis, HTML tag,
    code span or cell."""
    return _MD_PUNCTUATION.sub(r"\\\1", value)


def markdown_code(value: str) -> str:
    """``value`` as a Markdown code span (shown verbatim): fenced by one backtick more than its
    longest run of backticks, padded by a space where it starts or ends with one. Not for a table
    cell (a ``|`` would still split the cell there): :func:`markdown_text` is."""
    runs = [len(r) for r in re.findall(r"`+", value)]
    fence = "`" * (max(runs, default=0) + 1)
    pad = " " if value.startswith("`") or value.endswith("`") else ""
    return f"{fence}{pad}{value}{pad}{fence}"


# --------------------------------------------------------------------------------------------- C
def c_comment(value: str) -> str:
    """``value`` as text inside a C block comment: ``\\`` doubled, and ``*/`` (the comment's end),
    ``/*`` (gcc's -Wcomment) and ``??`` (a trigraph, read in C99) broken by a backslash."""
    text = value.replace("\\", "\\\\")
    text = text.replace("*/", "*\\/").replace("/*", "/\\*")
    return re.sub(r"\?(?=\?)", r"?\\", text)  # "???/" -> "?\?\?/": no two "?" in a row


#: The headers of the C standard library (C99 to C23): no generated header takes one of their names.
C_STANDARD_HEADERS = frozenset(
    "assert complex ctype errno fenv float inttypes iso646 limits locale math setjmp signal stdalign "
    "stdarg stdatomic stdbit stdbool stdckdint stddef stdint stdio stdlib stdnoreturn string tgmath "
    "threads time uchar wchar wctype".split()
)
#: C's keywords (C23 included): no prefix is one.
C_KEYWORDS = frozenset(
    "auto break case char const continue default do double else enum extern float for goto if inline int "
    "long register restrict return short signed sizeof static struct switch typedef union unsigned void "
    "volatile while alignas alignof bool constexpr false nullptr static_assert thread_local true typeof "
    "typeof_unqual".split()
)


def _ascii_identifier(value: str) -> str:
    """The file stem of ``value`` as an ASCII identifier: ``-`` as ``_``, no leading ``_`` (names
    starting so are reserved in C), ``m_`` before a leading digit."""
    s = file_stem(value).replace("-", "_").lstrip("_") or "mechanism"
    return "m_" + s if s[0].isdigit() else s


def c_identifier(value: str) -> str:
    """A C identifier (the prefix of the generated functions and the stem of the ``.h``/``.c``
    files) from a name: ``exo5-3d`` -> ``exo5_3d``; ``m_`` before a keyword or the name of a
    standard header (``math`` -> ``m_math``)."""
    s = _ascii_identifier(value)
    return "m_" + s if s.lower() in C_STANDARD_HEADERS or s in C_KEYWORDS else s


# ---------------------------------------------------------------------------------------- Python
#: What a generated Python module imports, besides the standard library.
PYTHON_IMPORTS = frozenset({"numpy"})


def python_module_name(value: str) -> str:
    """The module name (and file stem) of a generated Python module from a name: an ASCII
    identifier; ``m_`` before a keyword, a standard module's name or one the module imports
    (:data:`PYTHON_IMPORTS`), so that it never shadows them (``numpy`` -> ``m_numpy``)."""
    s = _ascii_identifier(value)
    taken = sys.stdlib_module_names | set(sys.builtin_module_names) | PYTHON_IMPORTS
    return "m_" + s if keyword.iskeyword(s) or s in taken or s.lower() in taken else s


def python_string(value: str) -> str:
    """``value`` as a Python string literal (its ``repr``: quotes and backslashes escaped)."""
    return repr(str(value))


def python_docstring(text: str) -> str:
    """``text`` inside a ``\"\"\"`` docstring: ``\\`` doubled and every ``\"`` escaped, so it can
    neither end the string nor start an escape."""
    return text.replace("\\", "\\\\").replace('"', '\\"')


def kind_of(mode: int) -> str:
    """``st_mode`` in words: "a FIFO", "a character device", ..."""
    for test, name in (
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
        (stat.S_ISDIR, "a folder"),
        (stat.S_ISREG, "a regular file"),
    ):
        if test(mode):
            return name
    return "not a regular file"


def output_target(path: str | Path, label: str = "", inputs=()) -> Path:
    """``path`` itself when it may be written: nothing is there, or a regular file that is not one
    of the command's ``inputs`` (paths it reads; a preset name is skipped). Otherwise one ValueError
    line naming it: an empty path, a trailing slash (a folder), a folder, a FIFO, a device, a
    socket, and ANY symlink, whatever it points to (a write never follows a link planted where a
    file goes). ``label`` prefixes the message (``"urdf -o"``)."""
    text = str(path)
    who = f"{label} {text!r}" if label else text
    if not text:
        raise ValueError(f"{label or 'output'}: expected a file to write, got an empty path")
    if "\0" in text:
        raise ValueError(f"{who}: expected a file to write, got a path with a NUL character")
    if text.endswith("/"):
        raise ValueError(f"{who}: names a folder (it ends with '/'); expected a file to write")
    p = Path(text)
    try:
        lst = os.lstat(p)
    except FileNotFoundError:
        return p
    except OSError as e:  # a name too long, a loop of links, a component that is a file
        if getattr(e, "errno", None) == errno.ENOTDIR:  # handled where the folder is made
            return p
        raise ValueError(f"{who}: not a usable path to write ({e.strerror or e})") from None
    if stat.S_ISLNK(lst.st_mode):
        raise ValueError(_link_refusal(p, who))
    if stat.S_ISDIR(lst.st_mode):
        raise ValueError(f"{text}: expected a file to write, got a folder")
    if not stat.S_ISREG(lst.st_mode):
        raise ValueError(f"{who}: is {kind_of(lst.st_mode)}; only a regular file or nothing is ever replaced")
    for source in inputs:
        try:
            same = os.path.samefile(source, p)
        except (OSError, ValueError, TypeError):  # a preset name, a missing file
            continue
        if same:
            raise ValueError(
                f"{who}: is the file this command reads ({str(source)!r}); refusing to overwrite its own input"
            )
    return p


def _link_refusal(p: Path, who: str) -> str:
    """The one line refusing the symlink ``p``: what it points to, and that it is never followed."""
    target = os.path.realpath(p)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return (
            f"{who}: is a symlink to {target!r}, which does not exist; refusing to write through a dangling "
            "link (remove it or point it at a file)"
        )
    except OSError as e:
        return f"{who}: is a symlink that cannot be followed ({e.strerror or e}); refusing to write through it"
    what = "a folder" if stat.S_ISDIR(st.st_mode) else kind_of(st.st_mode)
    if stat.S_ISREG(st.st_mode):
        return (
            f"{who}: is a symlink to {target!r}; a write never follows a link where a file goes "
            "(remove the link, or name the file itself)"
        )
    return f"{who}: is a symlink to {target!r}, which is {what}; only a regular file or nothing is ever replaced"


def write_all(fd: int, data: str | bytes) -> None:
    """All of ``data`` (text as UTF-8) to the descriptor ``fd``."""
    view = memoryview(data.encode() if isinstance(data, str) else data)
    while view:
        view = view[os.write(fd, view) :]


def _default_mode() -> int:
    """0666 less the umask (read from /proc where it can be, without changing it)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def _named(e: OSError, path: Path) -> OSError:
    """``e`` naming ``path`` (the file being written), not a temporary or nothing."""
    return OSError(e.errno, e.strerror or str(e), str(path))


@contextmanager
def replace_atomically(path: str | Path, label: str = "", inputs=()):
    """Yield ``(temporary path, its open descriptor)`` beside ``path``; on success the temporary
    is renamed over ``path``, on any error or Ctrl-C removed (never a half-written file).

    Safe in an output folder others may write: the folder is opened once and every step is taken
    relative to it; the temporary is created new (``O_EXCL | O_NOFOLLOW``), the name is checked
    again just before the rename (never a symlink: :func:`output_target`), and ``rename`` replaces
    a name, never what a link there points to. A replaced file keeps its mode; a new one gets
    0666 less the umask. Every OSError names ``path``."""
    import secrets

    p = output_target(path, label, inputs)
    parent = p.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ValueError(f"{p}: cannot make its folder {str(parent)!r}: {e.strerror or e}") from None
    try:
        dfd = os.open(parent, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as e:
        raise _named(e, p) from None
    fd, tmp = -1, ""
    try:
        try:
            old = os.lstat(p.name, dir_fd=dfd)
            mode = stat.S_IMODE(old.st_mode) if stat.S_ISREG(old.st_mode) else _default_mode()
        except FileNotFoundError:
            mode = _default_mode()
        flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC
        for _ in range(100):
            tmp = f".{p.name[:200]}.{secrets.token_hex(4)}.tmp"
            try:
                fd = os.open(tmp, flags, 0o600, dir_fd=dfd)
                break
            except FileExistsError:
                continue
        else:
            raise OSError(errno.EEXIST, "cannot create a temporary file beside it", str(p))
        try:
            yield parent / tmp, fd
            os.fchmod(fd, mode)
        except OSError as e:
            raise _named(e, p) from None
        output_target(p, label)  # a link planted while the file was written is refused too
        _still_ours(tmp, fd, dfd, p)
        try:
            os.replace(tmp, p.name, src_dir_fd=dfd, dst_dir_fd=dfd)
        except OSError as e:
            raise _named(e, p) from None
        tmp = ""
    finally:
        if fd >= 0:
            os.close(fd)
        if tmp:
            with suppress(OSError):
                os.unlink(tmp, dir_fd=dfd)
        os.close(dfd)


def _still_ours(tmp: str, fd: int, dfd: int, p: Path) -> None:
    """Refuse to publish when the temporary's name no longer holds the file this writer created
    (a writer that needs a file name opens it by name: one swapped for a link is never renamed into place)."""
    try:
        now, mine = os.lstat(tmp, dir_fd=dfd), os.fstat(fd)
    except OSError as e:
        raise _named(e, p) from None
    if not stat.S_ISREG(now.st_mode) or (now.st_dev, now.st_ino) != (mine.st_dev, mine.st_ino):
        raise ValueError(f"{p}: its temporary {tmp!r} was replaced while it was written; nothing was published")


def atomic_write(path: str | Path, data: str | bytes, label: str = "", inputs=()) -> Path:
    """``data`` (text as UTF-8) to ``path`` through :func:`replace_atomically`: whole or not at all."""
    with replace_atomically(path, label, inputs) as (_, fd):
        write_all(fd, data)
    return Path(path)


@contextmanager
def atomic_path(path: str | Path, label: str = "", inputs=()) -> Iterator[Path]:
    """Yield the temporary path of :func:`replace_atomically` for a writer that needs a file name;
    renamed over ``path`` when the block ends without error, removed otherwise."""
    with replace_atomically(path, label, inputs) as (tmp, _):
        yield tmp


__all__ = ["atomic_path", "atomic_write", "kind_of", "output_target", "replace_atomically", "write_all"]
