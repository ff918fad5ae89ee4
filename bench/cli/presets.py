"""``exo-bench presets``: the preset mechanisms."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    from exo_bench.bench.cli.arguments import subcommand

    subcommand(sub, "presets", cmd_presets, "list the preset mechanisms", "exo-bench presets")


def cmd_presets(args: argparse.Namespace) -> int:
    from exo_bench.models.mechanism.presets import preset_descriptions

    for name, desc in preset_descriptions().items():
        print(f"{name:10s} {desc}")
    return 0
