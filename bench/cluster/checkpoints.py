"""Checkpoints of a sweep: the code a sweep measures (:func:`code_key`), a folder per code, a file per
finished row (written atomically), so that a sweep run again after an interruption runs only the missing rows."""

from __future__ import annotations

import subprocess
from pathlib import Path

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
    """The checkpoint of one part of the stability study (JSON: bench/cluster/checkpoint_codec.py)."""
    return Path(folder) / f"{tag}.json"


def load_part(folder: Path, tag: str, result_type: str):
    """``(result, warnings)`` of the part ``tag`` checkpointed in ``folder``, or None when there is
    none; a file that is not such a part is one ValueError line naming it and the field. Never a
    pickle: a ``.pickle`` file there (from an older version, or planted) is never read."""
    from exo_bench.bench.cluster.checkpoint_codec import read_part

    p = part_file(folder, tag)
    if not p.exists() and not p.is_symlink():
        return None
    return read_part(read_checked(p, dict, "remove the file to run the part again"), tag, str(p), result_type)


def save_part(folder: Path, tag: str, part) -> Path:
    """Write the part ``(result, warnings)`` as JSON, atomically."""
    from exo_bench.bench.cluster.checkpoint_codec import part_text
    from exo_bench.models.files.atomic_files import atomic_write

    return atomic_write(part_file(folder, tag), part_text(tag, part))
