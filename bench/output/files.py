"""What every command may write over, how it writes, and which name a narrower run writes under.

* :func:`write_output` / :func:`replace_atomically`: the one writer behind every file the suite
  writes (``-o``, ``--reports``, the main job's publishing: :func:`move_into`;
  :func:`exo_bench.bench.output.provenance.atomic_write` and ``atomic_path`` call it). A file is
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

import errno
import os
import stat
import sys
from contextlib import contextmanager, suppress
from pathlib import Path


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


def write_all(fd: int, data: str | bytes) -> None:
    """All of ``data`` (text as UTF-8) to the descriptor ``fd``."""
    view = memoryview(data.encode() if isinstance(data, str) else data)
    while view:
        view = view[os.write(fd, view) :]


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

    (Path(staging) / OWNER).write_text(f"{os.getpid()} {_start_time(os.getpid())} {socket.gethostname()}\n")


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
