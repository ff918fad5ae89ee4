"""Blocks written by code into the page of highlights that the README links (:data:`HIGHLIGHTS`,
``reports/full/highlights.md``; until issue 38 they were in the README itself): the text between
``<!-- NAME:start -->`` and ``<!-- NAME:end -->`` is replaced, the rest left as it is (the paper table of
:mod:`~exo_bench.bench.perf.reports.paper_table`, issue 23's figures of
:mod:`~exo_bench.bench.perf.reports.simd_goals`). Nothing outside the markers is touched, and a
page without them is returned unchanged. Links inside a block are relative to the page's folder."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

#: The page of generated blocks, relative to the checkout: the full sweep's highlights, in its folder.
HIGHLIGHTS = Path("reports") / "full" / "highlights.md"


def markers(name: str) -> tuple[str, str]:
    """The start and end markers of block ``name``."""
    return f"<!-- {name}:start -->", f"<!-- {name}:end -->"


def replace_block(readme: str, name: str, body: str) -> str:
    """``readme`` with block ``name``'s text replaced by ``body`` (unchanged without its markers)."""
    start, end = markers(name)
    if start not in readme or end not in readme or readme.index(start) > readme.index(end):
        return readme
    head, rest = readme.split(start, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{start}\n{body}\n{end}{tail}"


def inserted_by(command: str, details: str) -> str:
    """The block's first line: the command, the date and the CPU that produced it, and where the
    details are."""
    from exo_bench.bench.output.provenance import machine_info

    info = machine_info()
    return f"_Inserted by `{command}` on {info['date (UTC)']} UTC ({info['cpu']}); {details}._"


def rewrite_highlights(update: Callable[[str], str]) -> Path | None:
    """Apply ``update`` to the checkout's :data:`HIGHLIGHTS` page and write it (atomically) only if it
    changed; the page's path if it did, else None. Nothing happens where there is no such page (an
    installed package)."""
    from exo_bench.bench.output.provenance import REPO
    from exo_bench.models.files import atomic_write

    path = REPO / HIGHLIGHTS
    if not path.exists():
        return None
    page = path.read_text()
    updated = update(page)
    if updated == page:
        return None
    atomic_write(path, updated)
    return path
