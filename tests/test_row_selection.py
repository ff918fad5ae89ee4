"""``exo-bench bench --rows PATTERN``: only the matching rows of the sweep (bench/cluster/commands.py)."""

import pytest

from exo_bench.bench.cli.app import build_parser
from exo_bench.bench.cluster.commands import selected_rows


def test_rows_are_selected_by_pattern_and_a_pattern_that_matches_nothing_is_named():
    keys = selected_rows(
        "full", ["*test_forward_dynamics.py:3d-chain-n10000", "*test_inverse_dynamics.py:3d-chain-n1000"]
    )
    assert keys == [
        "full:bench/test_forward_dynamics.py:3d-chain-n10000",
        "full:bench/test_inverse_dynamics.py:3d-chain-n1000",
    ] or sorted(keys) == sorted(
        ["full:bench/test_forward_dynamics.py:3d-chain-n10000", "full:bench/test_inverse_dynamics.py:3d-chain-n1000"]
    )
    quick = selected_rows("quick", ["*test_forward_dynamics.py:*"])
    assert quick and all(":bench/test_forward_dynamics.py:" in k for k in quick)
    assert not any(k.endswith("-n10000") for k in quick)  # CI's profile stays small
    with pytest.raises(ValueError, match="no row of the quick sweep matches 'nothing-\\*'"):
        selected_rows("quick", ["nothing-*"])


def test_the_bench_command_takes_repeated_row_patterns():
    args = build_parser().parse_args(["bench", "--full", "--rows", "a*", "--rows", "b*"])
    assert args.rows == ["a*", "b*"]
