"""A solver that ends without a solution is one exception type, :class:`SolveFailed`, raised by the
step's and the stride's problems and mapped to one line (exit 2) by the CLI's one handler
(bench/cli/app.py ``error_line``): ``gait --solve`` and ``stride --solve`` no longer each catch
RuntimeError, so an unforeseen RuntimeError is reported as an internal error, never as a failed solve.

The solver is forced to fail by a stand-in for ``casadi.nlpsol`` (no IPOPT run): its stats say
``success: False`` after 7 iterations.
"""

from __future__ import annotations

import pytest

pytest.importorskip("casadi")

from cli_runs import run_cli  # noqa: E402

from exo_bench.bench.output.interrupts import SolveFailed  # noqa: E402
from exo_bench.models.mechanism.presets import exo5, human  # noqa: E402

COMMANDS = [["gait", "--solve", "--dim", "2"], ["stride", "--solve", "--speed", "1.41"]]


class _FailingSolver:
    """What ``casadi.nlpsol`` returns, for a solve that stops without a solution."""

    def __call__(self, **_):
        import casadi

        return {"x": casadi.DM.zeros(1), "g": casadi.DM.zeros(1)}

    def stats(self):
        return {"success": False, "return_status": "Maximum_Iterations_Exceeded", "iter_count": 7}


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0])
def test_a_failed_solve_is_one_line_exit_2_from_the_one_handler(command, monkeypatch):
    """A solve that ends without a solution is one line naming the problem, IPOPT's status and its
    iterations, exit 2, nothing on stdout and nothing written."""
    import casadi

    monkeypatch.setattr(casadi, "nlpsol", lambda *a, **k: _FailingSolver())
    rc, out, err = run_cli(command)
    assert rc == 2 and out == "" and err.count("\n") == 1, err
    assert err.startswith("exo-bench: error: ") and "IPOPT did not solve" in err
    assert "Maximum_Iterations_Exceeded after 7 iterations" in err and "internal error" not in err


@pytest.mark.parametrize("command", COMMANDS, ids=lambda c: c[0])
def test_both_problems_raise_solve_failed_and_other_runtime_errors_are_internal(command, monkeypatch):
    """The problems raise :class:`SolveFailed` (a RuntimeError); a RuntimeError of another cause (a
    bug) is not mistaken for a failed solve: it is reported as an internal error (before: 'error')."""
    import casadi

    from exo_bench.bench.studies.step import problem as step
    from exo_bench.bench.studies.stride import problem as stride

    monkeypatch.setattr(casadi, "nlpsol", lambda *a, **k: _FailingSolver())
    with pytest.raises(SolveFailed, match="did not solve") as e:
        if command[0] == "gait":
            step.solve(exo5(2), step.StepSettings(dim=2))
        else:
            stride.solve_stages(human(2), stride.settings_for(human(2), "human", 1.41))
    assert isinstance(e.value, RuntimeError) and e.value.stats["iter_count"] == 7

    def broken(*a, **k):
        raise RuntimeError("a bug, not IPOPT")

    for module, name in [(step, "solve"), (stride, "solve_stages"), (stride, "solve_from")]:
        monkeypatch.setattr(module, name, broken)
    rc, _, err = run_cli(command)
    assert rc == 2 and err == "exo-bench: internal error: RuntimeError: a bug, not IPOPT (please report it)\n", err
