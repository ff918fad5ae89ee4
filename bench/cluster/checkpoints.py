"""Checkpoints of a sweep: the code a sweep measures (:func:`code_key`), a folder per code, a file per
finished row (written atomically), so that a sweep run again after an interruption runs only the missing rows."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from exo_bench.bench.perf import rows as _rows
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


def default_checkpoints(reports: Path) -> Path:
    """The checkpoint folder of a reports folder: ``.exo-bench-sweep`` beside it (never inside it,
    so an interrupted sweep leaves nothing in the reports folder)."""
    return Path(reports).resolve().parent / ".exo-bench-sweep"


def load_checkpoint(folder: Path, key: str) -> dict | None:
    p = folder / f"{_rows.safe_name(key)}.json"
    try:
        rec = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    return rec if rec.get("key") == key and rec.get("status") in FINAL else None
