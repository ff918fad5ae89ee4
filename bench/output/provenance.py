"""Shared report plumbing: atomic writes, run identifiers and the provenance header every report carries.

Every process that writes reports has one **run identifier** (:func:`current_run_id`: the UTC
start time and a random suffix, e.g. ``20260101T120000Z-3fa2``); the main job sets a new one per
run (:func:`set_run_id`). :func:`provenance` writes it into every Markdown report, :func:`save_figure`
into every PNG's metadata, and ``exo-bench run`` records it per file in ``runs.json`` and
``summary.md`` (bench/cli/run.py), so that every file in a reports folder says which run made it.
"""

from __future__ import annotations

import datetime as _dt
import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path

# The one writer (models/files.py: never through a symlink, whole or not at all, a replaced file
# keeps its mode, every error names the file). atomic_path is re-exported only for the stored step's and
# stride's data.py (another session's files in this change): they should import it from models/files.py.
from exo_bench.models.files import atomic_path as atomic_path, atomic_write

#: The source checkout when exo-bench runs from one (editable install); for a regular install this
#: is the installed package folder, which has no git metadata and no README.
REPO = Path(__file__).resolve().parents[2]
#: The default output folder: ``./reports`` in the current directory (a relative path, resolved
#: when it is used), so that an installed exo-bench writes where the user runs it.
REPORTS = Path("reports")


def sci(x, digits: int = 1) -> str:
    """A report cell in scientific notation: ``""`` for None or NaN, ``"inf"`` for infinity."""
    import math

    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    return "inf" if math.isinf(x) else f"{x:.{digits}e}"


#: Every PNG the suite writes: 150 dpi, so that 9 pt text is 19 px high.
PNG_DPI = 150


def literal_texts(fig) -> None:
    """Every text of ``fig`` outside its axes (titles, legends, figure texts: where a scene's or a
    link's name is shown) drawn as written, never as mathtext: matplotlib reads ``$...$`` as math,
    and a link named ``a$\\x$b`` stopped the figure with a parse error. The axes' own texts keep
    mathtext (a log axis labels its ticks with it); the suite writes no math of its own in figures."""
    from matplotlib.text import Text

    axis_texts: set = set()
    for ax in fig.get_axes():
        for axis in (getattr(ax, k, None) for k in ("xaxis", "yaxis", "zaxis")):
            if axis is not None:
                axis_texts.update(axis.findobj(Text))
    for t in fig.findobj(Text):
        if t not in axis_texts:
            t.set_parse_math(False)


def save_figure(fig, path: str | Path, dpi: int = PNG_DPI) -> Path:
    """Render a matplotlib figure to PNG in memory and write it atomically (no half-written file),
    with the run identifier in the PNG's metadata (``Description: exo-bench run <id>``); names in
    it are text (:func:`literal_texts`)."""
    import io

    literal_texts(fig)
    buf = io.BytesIO()
    fig.savefig(
        buf,
        format="png",
        dpi=dpi,
        metadata={"Software": "exo-bench", "Description": f"exo-bench run {current_run_id()}"},
    )
    return atomic_write(path, buf.getvalue())


# ------------------------------------------------------------------------------ run identifiers
_RUN_ID: list[str] = []

#: How a run identifier appears in a report's provenance block (parsed back by :func:`run_id_of`).
RUN_LINE = "- **run**: "


def new_run_id() -> str:
    """A fresh identifier: the UTC time and 4 random hex digits (``20260101T120000Z-3fa2``)."""
    import secrets

    return _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ") + "-" + secrets.token_hex(2)


def set_run_id(run_id: str) -> str:
    """Make ``run_id`` the identifier of what this process writes from now on."""
    _RUN_ID[:] = [run_id]
    return run_id


def current_run_id() -> str:
    """This process's run identifier (made on first use)."""
    if not _RUN_ID:
        _RUN_ID.append(new_run_id())
    return _RUN_ID[0]


def run_id_of(path: str | Path) -> str | None:
    """The run identifier a report file carries: the provenance line of a Markdown report, the
    metadata of a PNG; None when it carries none (older files, recordings, JSON)."""
    import re

    path = Path(path)
    try:
        if not path.is_file():  # a FIFO or a device would block or never end
            return None
        if path.suffix == ".md":
            with open(path, encoding="utf-8", errors="replace") as f:
                for _, line in zip(range(40), f):
                    if line.startswith(RUN_LINE):
                        return line[len(RUN_LINE) :].strip().strip("`") or None
        elif path.suffix == ".png":
            head = path.read_bytes()[:65536]
            m = re.search(
                rb"exo-bench run ([0-9]{8}T[0-9]{6}Z-[0-9a-f]{4})", head
            )  # 4 hex digits, then binary (the CRC)
            return m.group(1).decode() if m else None
    except OSError:
        return None
    return None


def _version(pkg: str) -> str:
    try:
        return metadata.version(pkg)
    except metadata.PackageNotFoundError:
        return "not installed"


def _git_commit() -> str:
    try:
        out = subprocess.run(
            ["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, timeout=5
        )
        # Generated files (reports/, the README's inserted table) do not make the code "uncommitted".
        dirty = subprocess.run(
            [
                "git",
                "-C",
                str(REPO),
                "status",
                "--porcelain",
                "--untracked-files=no",
                "--",
                ".",
                ":!reports",
                ":!README.md",
            ],
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
        return (out.stdout.strip() or "unknown") + (" (with uncommitted changes)" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine_info() -> dict[str, str]:
    return {
        "date (UTC)": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S"),
        "host": platform.node(),
        "cpu": f"{_cpu_model()}, {os.cpu_count()} logical cores",
        "os": platform.platform(),
        "python": sys.version.split()[0],
        "packages": ", ".join(f"{p} {_version(p)}" for p in ("pin", "numpy", "sympy", "pandas", "rerun-sdk")),
        "commit": _git_commit(),
    }


def provenance(command: str) -> str:
    """A Markdown block saying what produced a report, on what machine and when."""
    from exo_bench.models.files import markdown_code

    lines = [f"_Generated by {markdown_code(command)}; do not edit by hand._", ""]  # a name in it stays text
    lines += [f"{RUN_LINE}`{current_run_id()}`"]
    lines += [f"- **{k}**: {v}" for k, v in machine_info().items()]
    return "\n".join(lines) + "\n"


def writable_folder(value, label: str) -> Path:
    """A folder named on the command line (``label`` names the option in the message, e.g.
    ``--reports`` or ``equations -o``): one that exists or can be made and can be written, refused in
    words when it is empty, names a file (or lies under one) or cannot be written; checked before
    any work starts."""
    text = str(value)
    if not text.strip():
        raise ValueError(f"{label}: expected a folder, got an empty path")
    if text == "-":
        raise ValueError(f"{label} '-': expected a folder; stdout cannot take the several files this command writes")
    if "\0" in text:
        raise ValueError(f"{label} {text!r}: expected a folder, got a path with a NUL character")
    p = Path(text)
    try:
        for parent in [p, *p.parents]:
            if parent.is_symlink() and not parent.exists():  # a dangling link: mkdir would say "File exists"
                where = "is" if parent == p else f"lies under {str(parent)!r}, which is"
                raise ValueError(
                    f"{label} {text!r}: expected a folder, but it {where} a symlink to "
                    f"{os.path.realpath(parent)!r}, which does not exist"
                )
            if parent.exists():
                if not parent.is_dir():
                    what = "a file" if parent.is_file() else "a device, FIFO or socket"
                    where = f"is {what}" if parent == p else f"lies under {str(parent)!r}, which is {what}"
                    raise ValueError(f"{label} {text!r}: expected a folder, but it {where}")
                if not os.access(parent, os.W_OK | os.X_OK):
                    raise ValueError(
                        f"{label} {text!r}: the folder {str(parent)!r} cannot be written (permission denied)"
                    )
                break
    except OSError as e:  # a name too long, a loop of links, ...
        raise ValueError(f"{label} {text!r}: not a usable folder ({e.strerror or e})") from None
    return p
