"""The README's links under ``reports/`` are honest about which run wrote them (issue 38: "the files the
README links under reports/ carry this run's id"; the README linked reports/full/*.md, which the first
command does not write, beside the reports it does).

Every ``](reports/...)`` link of the README is either a file the default main job (``exo-bench run``, the
README's first command) publishes, and so carries that run's id (tests/test_main_job_places.py checks the
committed ones do), or a file under ``reports/full/`` in a paragraph that names the ``--full`` command that
writes it. Nothing else under reports/ is linked (a screenshot, a file of an older run).
"""

from __future__ import annotations

import re
from pathlib import Path

from test_main_job_places import default_run_files

from exo_bench.bench.output.publish import FULL_FOLDER

README = Path(__file__).resolve().parents[1] / "README.md"
LINK = re.compile(r"\]\(reports/([^)#\s]+)(?:#[^)\s]*)?\)")


def report_links(text: str) -> list[tuple[str, str]]:
    """(path under reports/, the paragraph holding the link) of every link under reports/ in ``text``;
    a paragraph is a block between blank lines (a table is one paragraph)."""
    return [(m.group(1), para) for para in re.split(r"\n\s*\n", text) for m in LINK.finditer(para)]


def misplaced(links: list[tuple[str, str]], written: set[str]) -> list[str]:
    """The links that are neither a file of the default run nor a ``--full`` file labelled as such."""
    bad = []
    for path, para in links:
        if path in written:
            continue
        if path.startswith(f"{FULL_FOLDER}/") and "--full" in para:
            continue
        bad.append(path)
    return bad


def test_the_check_catches_an_unlabelled_or_foreign_link():
    """The check can fail: a full-sweep link without its command, and a file no run writes."""
    text = "See [a](reports/summary.md).\n\n[b](reports/full/scaling.md) is the sweep's.\n\n![c](reports/shot.png)\n"
    assert misplaced(report_links(text), {"summary.md"}) == ["full/scaling.md", "shot.png"]
    labelled = "From `exo-bench run --full`: [b](reports/full/scaling.md)."
    assert misplaced(report_links(labelled), set()) == []


def test_every_reports_link_of_the_readme_is_the_first_commands_or_labelled_full():
    links = report_links(README.read_text())
    assert any(p == "summary.md" for p, _ in links)  # the README does point into reports/
    assert not misplaced(links, default_run_files()), (
        "README links under reports/ that the first command does not write and that are not labelled as "
        f"--full's: {misplaced(links, default_run_files())}"
    )
