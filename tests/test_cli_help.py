"""``--help`` of the command line (issue 38): every subcommand says in one line what it does and
shows an example that parses as written; ``run --help`` lists the scenes the loader finds; the
top-level help's count of methods is the method table's, never typed."""

from __future__ import annotations

import argparse
import shlex

import pytest

from exo_bench.bench.cli.app import SUBCOMMANDS, build_parser


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


def _examples(p: argparse.ArgumentParser) -> list[str]:
    return [line.strip() for line in (p.epilog or "").splitlines() if line.strip().startswith("exo-bench ")]


@pytest.mark.parametrize("name", SUBCOMMANDS)
def test_every_subcommand_has_a_description_and_an_example_that_parses(name):
    sub = _subparsers()[name]
    assert sub.description and sub.description.strip(), f"{name}: no description in --help"
    assert "\n" not in sub.description.strip(), f"{name}: the description is not one line"
    examples = _examples(sub)
    assert examples, f"{name}: no example line in --help"
    for line in examples:
        argv = shlex.split(line)[1:]
        assert argv[0] in SUBCOMMANDS, f"{name}: example {line!r} names no subcommand"
        build_parser().parse_args(argv)  # as written: a usage error raises
    assert any(shlex.split(x)[1] == name for x in examples), f"{name}: no example runs {name} itself"
    text = sub.format_help()
    assert sub.description.strip() in " ".join(text.split()) or sub.description.strip()[:40] in text
    assert examples[0] in text  # the example is shown as written, not re-wrapped


def test_run_help_lists_every_scene_the_loader_finds():
    from exo_bench.bench.studies.scenes import shipped_scene_names

    names = shipped_scene_names()
    assert names
    text = _subparsers()["run"].format_help()
    for n in names:
        assert n in text.split(), f"run --help does not list scene {n!r}"


def test_top_level_help_counts_the_methods_of_the_table():
    from exo_bench.api.methods import method_names

    text = build_parser().format_help()
    assert "three implementations" not in text
    count = len(method_names())
    assert f"{count} methods" in " ".join(text.split())
    for m in method_names():
        assert m in text
