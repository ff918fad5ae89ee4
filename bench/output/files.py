"""What every command may write over, how it writes, and which name a narrower run writes under.

* :func:`write_output` / :func:`replace_atomically` (:mod:`exo_bench.models.files`): the one
  writer behind every file the suite writes (``-o``, ``--reports``, the main job's publishing: :func:`move_into`;
  :mod:`exo_bench.models.files`' ``atomic_write`` and ``atomic_path`` are the same writer). A file is
  written only where there is nothing or a regular file (:func:`output_target`): a symlink (to
  anything), a FIFO, a device, a socket or a folder is refused in one line (a ValueError, exit 2
  from the CLI), and so is the command's own input. The write goes to a new temporary file in the
  same folder (``O_EXCL | O_NOFOLLOW``, relative to the folder's descriptor), renamed over the name:
  never through a link planted there, never half-written; a replaced file keeps its mode, and every
  OSError names the file. ``-o -``, and a path that is this process's stdout (``/dev/stdout`` into a
  log), are written as a stream (:func:`stream_of`), never replaced.
* :func:`narrower_names`: "a narrower run never overwrites a wider one", for every report. The
  benchmark reports started it (``bench.bench_reports.report_names``): when a report in the folder
  comes from a ``--full`` run (its entry in ``runs.json``, or its own provenance line), a quick run
  writes ``<name>-quick.<ext>`` beside it.
* :func:`stale_staging`: the ``.staging-*`` folders a killed run left behind (each staging folder
  holds its owner's process id and start time), removed by the next run that stages into the folder.
"""

from __future__ import annotations

import os
import stat
import sys
from contextlib import contextmanager
from pathlib import Path

from exo_bench.models.files import (  # the one writer, in models so that every layer can use it
    _named,
    atomic_write,
    output_target,
    replace_atomically,
    write_all,
)


# ------------------------------------------------------------------------------ the one writer
#: ``-o -``: the command's stdout.
STDOUT = "-"


def stream_of(path: str | Path):
    """The text stream ``path`` means, or None for a file: ``-`` is stdout; a path that is this
    process's stdout or stderr (``/dev/stdout``, ``/proc/self/fd/1``, the log file stdout is
    appended to) is that stream, written as a stream and never replaced."""
    text = str(path)
    if text == STDOUT:
        return sys.stdout
    if not text or "\0" in text:
        return None
    try:
        st = os.stat(text)
    except (OSError, ValueError):
        return None
    for fd, stream in ((1, sys.stdout), (2, sys.stderr)):
        try:
            own = os.fstat(fd)
        except OSError:
            continue
        if (own.st_dev, own.st_ino) == (st.st_dev, st.st_ino):
            return stream
    return None


def write_output(path: str | Path, data: str | bytes, label: str = "", inputs=()) -> Path | None:
    """The one writer of the command line: ``data`` to ``path`` atomically (:func:`replace_atomically`),
    or to the stream ``path`` means (:func:`stream_of`: stdout, written and flushed, None returned)."""
    stream = stream_of(path)
    if stream is not None:
        with stream_errors("stdout" if stream is sys.stdout else "stderr"):
            if isinstance(data, bytes):
                stream.flush()
                stream.buffer.write(data)
            else:
                stream.write(data)
            stream.flush()
        return None
    _existing_folder(path, label)
    with replace_atomically(path, label, inputs) as (_, fd):
        write_all(fd, data)
    return Path(path)


@contextmanager
def stream_errors(name: str = "stdout"):
    """An OSError writing a stream (stdout full: ``> /dev/full``) names it, as a file's error names
    the file; a broken pipe stays a BrokenPipeError (the command line's exit 141)."""
    try:
        yield
    except BrokenPipeError:
        raise
    except OSError as e:
        if e.filename is not None:
            raise
        raise OSError(e.errno, e.strerror or str(e), name) from None


def checked_output(path: str | Path, label: str = "", inputs=()) -> None:
    """Before any work: refuse in one line what :func:`write_output` would refuse (a stream is fine)."""
    if stream_of(path) is None:
        output_target(path, label, inputs)
        _existing_folder(path, label)


def _existing_folder(path: str | Path, label: str = "") -> None:
    """A file a user names (``-o``) goes into a folder that exists: a missing one is one ValueError
    line, never made (``urdf -o /nonexistent/dir/x.urdf`` made both folders). A parent that is a file
    is refused where the folder would be made (:func:`replace_atomically`)."""
    parent = Path(path).parent
    if not parent.exists() and not parent.is_symlink():
        who = f"{label} {str(path)!r}" if label else repr(str(path))
        raise ValueError(f"{who}: its folder {str(parent)!r} does not exist (make it first, or name another file)")


def move_into(source: Path, target: Path) -> Path:
    """Rename the finished file ``source`` (in the same file system) over ``target``, refusing
    what :func:`output_target` refuses and keeping a replaced file's mode (the publisher's step)."""
    target = output_target(target)
    try:
        old = os.lstat(target)
        os.chmod(source, stat.S_IMODE(old.st_mode))
    except FileNotFoundError:
        pass
    except OSError as e:
        raise _named(e, target) from None
    try:
        os.replace(source, target)
    except OSError as e:
        raise _named(e, target) from None
    return target


# ------------------------------------------------------------------------------ narrower never overwrites wider
GENERATED = "_Generated by `"


def _own_command(path: Path) -> str:
    """The command a Markdown report says made it (its provenance line), or ""."""
    if path.suffix != ".md" or not path.is_file():
        return ""
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            for _, line in zip(range(10), f):
                if line.startswith(GENERATED):
                    return line[len(GENERATED) :].split("`", 1)[0]
    except OSError:
        return ""
    return ""


def wider_run_there(out: Path, names) -> str:
    """The command of a ``--full`` run that wrote one of ``names`` in ``out`` (runs.json first,
    then the file's own provenance line), or ""."""
    import json

    out = Path(out)
    if not out.is_dir():
        return ""
    try:
        if not (out / "runs.json").is_file():
            raise OSError
        manifest = json.loads((out / "runs.json").read_text())
        manifest = manifest if isinstance(manifest, dict) else {}
    except (OSError, ValueError):
        manifest = {}
    for n in names:
        try:
            cmd = str(manifest["runs"][manifest["files"][n]["run"]]["command"])
        except (KeyError, TypeError):
            continue
        if "--full" in cmd:
            return cmd
    for n in names:
        cmd = _own_command(out / n)
        if "--full" in cmd:
            return cmd
    return ""


def quick_name(name: str) -> str:
    p = Path(name)
    return f"{p.stem}-quick{p.suffix}"


def has_line(out: Path, names, line: str) -> bool:
    """Whether a Markdown report of one of ``names`` in ``out`` has a line starting with ``line``."""
    for n in names:
        p = Path(out) / n
        if n.endswith(".md") and p.is_file():
            try:
                text = p.read_text(errors="replace")
            except OSError:
                continue
            if any(x.startswith(line) for x in text.splitlines()):
                return True
    return False


def narrower_names(out: Path, names, full: bool, lacks: str = "") -> dict[str, str]:
    """``name -> the name to write`` in ``out``: the names themselves for a full run, or when no
    ``--full`` run wrote any of them; else ``<name>-quick.<ext>`` for each (never over the wider run).
    ``lacks``: the start of a line that the report there may have and this run cannot write (a part
    that needs an extra not installed here); a report there with it is wider too, full run or not."""
    names = list(names)
    if lacks and has_line(out, names, lacks):
        return {n: quick_name(n) for n in names}
    if full or not wider_run_there(out, names):
        return {n: n for n in names}
    return {n: quick_name(n) for n in names}


def announce_narrower(out: Path, names: dict[str, str], what: str, why: str = "come from a full run") -> None:
    """One stdout line when a narrower run writes beside a wider run's reports (``why`` they are wider)."""
    if any(k != v for k, v in names.items()):
        shown = ", ".join(v for v in names.values() if v.endswith(".md")) or ", ".join(names.values())
        print(f"{out}: the {what} there {why}; this run writes {shown} beside them", flush=True)


# ------------------------------------------------------------------------------ stale staging folders
OWNER = ".owner"


def _start_time(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return ""


def mark_owner(staging: Path) -> None:
    """Write this process's id and start time into its staging folder (:func:`stale_staging`)."""
    import socket

    atomic_write(Path(staging) / OWNER, f"{os.getpid()} {_start_time(os.getpid())} {socket.gethostname()}\n")


def _alive(owner: str) -> bool | None:
    """Whether the process an owner line names still runs (None: not known here)."""
    import socket

    parts = owner.split()
    if len(parts) != 3 or parts[2] != socket.gethostname():
        return None
    try:
        pid = int(parts[0])
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, ValueError, OverflowError):
        return None
    start = _start_time(pid)
    return not (start and parts[1] and start != parts[1])  # the pid was reused by another process


#: A staging folder without an owner mark (an older version's) is taken as stale after this long.
UNMARKED_STALE_SECONDS = 24 * 3600


def stale_staging(out: Path) -> tuple[list[Path], list[Path]]:
    """``(stale, unknown)`` ``.staging-*`` folders of ``out``: those whose owner is gone (or
    unmarked and older than a day), and those whose owner cannot be told (another host, too young)."""
    import time

    stale: list[Path] = []
    unknown: list[Path] = []
    try:
        entries = [
            d for d in Path(out).iterdir() if d.name.startswith(".staging-") and d.is_dir() and not d.is_symlink()
        ]
    except OSError:
        return [], []
    for d in entries:
        try:
            if not (d / OWNER).is_file():
                raise OSError
            alive = _alive((d / OWNER).read_text())
        except OSError:
            try:
                old = time.time() - d.stat().st_mtime > UNMARKED_STALE_SECONDS
            except OSError:
                continue
            alive = False if old else None
        (stale if alive is False else unknown if alive is None else []).append(d)
    return stale, unknown


def clean_stale_staging(out: Path) -> None:
    """Remove the staging folders killed runs left in ``out``; one warning line says how many, and
    one more names those left alone (their owner may still be running elsewhere)."""
    import shutil
    import sys

    stale, unknown = stale_staging(out)
    for d in stale:
        shutil.rmtree(d, ignore_errors=True)
    if stale:
        print(
            f"exo-bench: warning: removed {len(stale)} staging folder(s) left in {str(out)!r} by a run that was "
            f"killed ({', '.join(d.name for d in stale)})",
            file=sys.stderr,
        )
    if unknown:
        print(
            f"exo-bench: warning: left {len(unknown)} staging folder(s) in {str(out)!r} whose run may still be "
            f"going on ({', '.join(d.name for d in unknown)}); remove them by hand if it is not",
            file=sys.stderr,
        )
