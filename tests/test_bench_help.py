"""``exo-bench bench --help`` says what ``--full`` runs, generated from the full sweep's definition
(it said "n up to 100" while the full sweep goes to n = 1000 and newton-euler alone to 10,000)."""

from __future__ import annotations

import dataclasses

from exo_bench.bench.cli import bench
from exo_bench.bench.perf import profiles


def _help(parser_args=("bench", "--help")) -> str:
    from exo_bench.bench.cli.app import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if a.choices and "bench" in a.choices).choices["bench"]
    return " ".join(sub.format_help().split())


def test_the_help_names_the_full_sweeps_largest_models():
    text = _help()
    full = profiles.FULL
    largest = max((*full.inverse_n, *full.scaling_n, *full.forward_n))
    assert f"n up to {largest:,}" in text, text
    assert f"{max(full.newton_euler_n):,}" in text and f"{full.samples:,} samples" in text
    assert "n up to 100," not in text


def test_the_help_follows_the_definition(monkeypatch):
    """Another full sweep, another help text: nothing in it is written by hand."""
    other = dataclasses.replace(profiles.FULL, scaling_n=(300,), forward_n=(7,), newton_euler_n=(), samples=500)
    monkeypatch.setattr(profiles, "FULL", other)
    text = bench.full_help()
    assert "n up to 300" in text and "500 samples" in text and "newton-euler" not in text
