"""The README's run hands the costliest files out first (tests/xdist_workers.py, ``COSTLY_FIRST``)."""

from __future__ import annotations

from pathlib import Path

from xdist_workers import COSTLY_FIRST, SHARED_WORKER, costly_first

ROOT = Path(__file__).resolve().parent.parent


def test_every_listed_file_or_group_exists_once():
    """A renamed or deleted file would silently lose its place: each entry is a file of the suite or a
    group of :data:`SHARED_WORKER`, and none is listed twice."""
    assert len(set(COSTLY_FIRST)) == len(COSTLY_FIRST)
    for scope in COSTLY_FIRST:
        assert scope in SHARED_WORKER.values() or (ROOT / scope).is_file(), scope
        assert scope not in SHARED_WORKER, f"{scope} runs in its group {SHARED_WORKER.get(scope)!r}: list the group"


def test_listed_scopes_come_first_in_their_order_and_the_rest_keep_theirs():
    rest = ["tests/test_a.py", "tests/test_b.py", "bench/test_c.py"]
    scopes = [rest[0], COSTLY_FIRST[2], rest[1], COSTLY_FIRST[0], rest[2]]
    assert costly_first(scopes) == [COSTLY_FIRST[0], COSTLY_FIRST[2], *rest]
