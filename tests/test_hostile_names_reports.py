"""Hostile names through the exporters tests/test_hostile_names.py does not reach (issue 34, done-when:
"a hypothesis strategy of names ... runs through every exporter"): a scene's Markdown reports
(its page, its equations page and summary.md), its rerun recording's entity paths, and its file names.

A scene of ``exo-bench run`` whose mechanism and link names are drawn from the names the name check
accepts (XML, LaTeX, Markdown, C and Python metacharacters, ``--``, code fences, HTML) is run beside
the same scene with plain names (one method, 8 samples): every Markdown file parses (markdown-it,
CommonMark with tables) into the same blocks, table rows and cells as the plain run's, shows each name whole wherever the
plain run shows its plain name, and holds no HTML from a name; every entity path of the recording is made of the file-name encoder's characters;
and the files written are those of the plain run. Hypothesis draws 2 examples (each a scene run: about 3 s of CPU).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from test_hostile_names import ACCEPTED

import exo_bench.bench.cli.run as runner
from exo_bench.bench.studies.options import RunOptions
from exo_bench.models.mechanism.presets import fig2a

SCENE = """name = "hostile"
mechanism = {mechanism}
methods = ["matrix-factored"]
outputs = ["table", "equations", "recording"]
[motion]
kind = "smooth-random"
duration = 1.0
samples = 8
"""


#: The plain run's mechanism and link names: words found nowhere else in a report.
PLAIN = ("Plainmech", "Plainlink")


def _run(d: Path, name: str, link: str) -> Path:
    """The scene of a fig2a-2d named ``name`` with a link named ``link``, run into ``d / "rep"``."""
    d.mkdir(parents=True, exist_ok=True)
    mech = fig2a(2).replace(name=name, names=(link, "thigh"))
    (d / "m.json").write_text(json.dumps(mech.to_dict()), encoding="utf-8")
    (d / "s.toml").write_text(SCENE.format(mechanism=json.dumps(str(d / "m.json"))), encoding="utf-8")
    assert runner.run_main_job(RunOptions(scenes=(str(d / "s.toml"),), reports=str(d / "rep"))) == 0
    return d / "rep"


def _blocks(text: str) -> tuple[list[str], list[str], str]:
    """The block tokens of a Markdown text (paragraphs, headings, table rows and cells...), the
    inline token types of HTML found in it, and its rendered text (text and code spans, one a line)."""
    from markdown_it import MarkdownIt

    tokens = MarkdownIt("commonmark").enable("table").parse(text)
    html = [c.type for t in tokens for c in (t.children or []) if c.type.startswith("html")]
    shown = "\n".join(c.content for t in tokens for c in (t.children or []) if c.type in ("text", "code_inline"))
    return [t.type for t in tokens if t.type != "inline"], html, shown


def _entities(monkeypatch) -> list[str]:
    """Every entity path the recordings log (the stream's log and send_columns, recorded)."""
    import rerun as rr

    from exo_bench.bench.output import recording

    seen: list[str] = []

    class Recorded(rr.RecordingStream):
        def log(self, entity, *a, **k):
            seen.append(entity)
            return super().log(entity, *a, **k)

        def send_columns(self, entity, *a, **k):
            seen.append(entity)
            return super().send_columns(entity, *a, **k)

    monkeypatch.setattr(recording.rr, "RecordingStream", Recorded)
    return seen


@pytest.fixture(scope="module")
def plain(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("plain"), PLAIN[0], PLAIN[1])


@given(name=ACCEPTED, link=ACCEPTED)
@settings(
    max_examples=2,
    deadline=None,
    suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.function_scoped_fixture],
)
def test_a_scenes_reports_and_recording_of_hostile_names_keep_their_structure(
    name, link, plain, tmp_path_factory, monkeypatch
):
    """The scene's Markdown files parse into the plain names' blocks, table rows and cells, with no
    HTML from a name; the recording's entity paths hold only the encoder's characters; the same files."""
    pytest.importorskip("rerun")
    entities = _entities(monkeypatch)
    rep = _run(tmp_path_factory.mktemp("hostile"), name, link)
    files = sorted(p.relative_to(rep).as_posix() for p in rep.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(plain).as_posix() for p in plain.rglob("*") if p.is_file())
    shown_plain = 0
    for md in [f for f in files if f.endswith(".md")]:
        got, html, shown = _blocks((rep / md).read_text(encoding="utf-8"))
        want, plain_html, plain_shown = _blocks((plain / md).read_text(encoding="utf-8"))
        assert got == want and html == plain_html, md
        for hostile, word in zip((name, link), PLAIN):  # shown whole wherever the plain name is (a '|' cut a cell)
            assert shown.count(hostile) >= plain_shown.count(word), (md, hostile)
        shown_plain += plain_shown.count(PLAIN[0])
    assert shown_plain >= 4  # the pages show the mechanism's name (4 times: the check above is not empty)
    assert entities and all(re.fullmatch(r"[A-Za-z0-9_\-]+(/[A-Za-z0-9_\-]+)*", e) for e in entities), entities
