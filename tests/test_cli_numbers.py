"""Every numeric option of every subcommand is read by one strict parser (issue 34, W8 at the CLI):
a decimal literal, ASCII digits with an optional sign, point and exponent, without underscores or
surrounding spaces. Python's ``float()`` and ``int()`` read ``"1.4_1"`` as 1.41, ``" 2 "`` as 2 and
``"١٢"`` as 12; ``exo-bench stride --speed 1.4_1`` described the 1.41 m/s stride, exit 0. A refusal is
one line naming the option, the expected form and the value, exit 2, before any work."""

from __future__ import annotations

import argparse

import pytest

from exo_bench.bench.cli import arguments
from exo_bench.bench.cli.app import _UsageError as UsageError
from exo_bench.bench.cli.app import build_parser, main

#: Text no number option may accept: underscores, surrounding or inner spaces, non-ASCII digits.
BAD = ("1_0", "1.4_1", " 2", "2 ", "\u0661\u0662", "1e1_0", "+ 1")
#: A valid literal of each option (a value it accepts), so that a refusal is the text's, not its range.
GOOD = {"--speed": "1.41", "--dim": "2", "--seed": "3", "--samples": "4", "--workers": "2"}


def _numeric_options():
    """``(subcommand, option)`` of every option whose value is a number: its type is one of the
    parsers of :mod:`exo_bench.bench.cli.arguments` or a subcommand's own, never bare float or int."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    found = []
    for name, sp in sub.choices.items():
        for action in sp._actions:
            if action.type is not None and action.option_strings:
                found.append((name, action))
    return found


def test_no_option_reads_numbers_with_bare_float_or_int():
    bare = [(n, a.option_strings[-1]) for n, a in _numeric_options() if a.type in (float, int, str)]
    assert not bare, f"options typed float/int/str instead of the strict parser: {bare}"


@pytest.mark.parametrize(
    "command, option", [(n, a.option_strings[-1]) for n, a in _numeric_options() if a.type not in (str,)]
)
@pytest.mark.parametrize(
    "text",
    BAD,
    ids=["underscore", "underscore-point", "lead-space", "trail-space", "arabic", "exponent-underscore", "inner-space"],
)
def test_every_numeric_option_refuses_a_loose_literal(command, option, text):
    """Parsed only (no command runs, whatever is accepted): the parser's one-line error names the
    option, the expected form and the value (main prints it and exits 2: the stride test below)."""
    with pytest.raises(UsageError) as err:
        build_parser().parse_args([command, f"{option}={text}"])
    line = str(err.value)
    assert "\n" not in line and option in line and repr(text) in line and "expected" in line, line


@pytest.mark.parametrize(
    "text, value", [("1.41", 1.41), ("-2", -2.0), ("+.5", 0.5), ("3.", 3.0), ("1e3", 1000.0), ("2E-1", 0.2)]
)
def test_the_strict_parser_reads_decimal_literals(text, value):
    assert arguments.decimal(text) == value


@pytest.mark.parametrize("text", [*BAD, "", "nan", "inf", "0x10", "1e", ".", "1.2.3", "1,5"])
def test_the_strict_parser_refuses_everything_else(text):
    with pytest.raises(argparse.ArgumentTypeError, match="expected a decimal number"):
        arguments.decimal(text)


def test_stride_speed_with_an_underscore_is_refused_not_read_as_1_41(capsys):
    """The probe's reproduction: before, 1.4_1 was the stored 1.41 m/s stride."""
    assert main(["stride", "--speed", "1.4_1"]) == 2
    err = capsys.readouterr().err
    assert "--speed" in err and "'1.4_1'" in err
