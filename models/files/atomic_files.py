"""The one writer of every file the package writes: atomic, never through a link, never half-written.

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
import os
import stat
from collections.abc import Iterator
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
