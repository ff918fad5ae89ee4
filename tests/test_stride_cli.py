"""``exo-bench stride`` (issue 37): describes a stored stride with its constraints re-evaluated, and refuses
bad input in one line with exit 2 before any work (no solve is started here: ``--solve`` is exercised by the
slow reproduction test of tests/test_stride.py through the same :func:`~.problem.solve`)."""

from __future__ import annotations

import pytest

from exo_bench.bench.cli.app import main


def _run(capsys, *argv):
    code = main(["stride", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_describes_the_stored_stride_with_its_constraints(capsys):
    code, out, err = _run(capsys, "--variant", "exo", "--speed", "1.41")
    assert code == 0, err
    assert "exo variant: one stride of 0.9870 s" in out
    worst = float(out.split("largest violation ")[1].split()[0])
    assert worst <= 1e-8


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--speed", "fast"], "argument --speed: expected a decimal number such as 1.41, got 'fast'"),
        (["--speed", "1.4_1"], "argument --speed: expected a decimal number such as 1.41, got '1.4_1'"),
        (["--speed", "-1"], "expected a speed in (0, 10) m/s"),
        (["--speed", "1.234"], "in steps of 0.01"),
        (["--speed", "inf"], "argument --speed: expected a decimal number such as 1.41, got 'inf'"),
        (["--speed", "1e9"], "expected a speed in (0, 10) m/s"),
        (["--speed", "1.23"], "no stored stride human-2d-human-v123.npz"),
        (["--store"], "--store needs --solve"),
        (["--variant", "robot"], "invalid choice: 'robot'"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(capsys, argv, words):
    code, out, err = _run(capsys, *argv)
    assert code == 2 and out == ""
    assert words in err and len(err.strip().splitlines()) == 1, err
