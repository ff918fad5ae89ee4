"""The one exception of a numerical solve that ends without a solution (IPOPT in the step's and the
stride's problems): the command line's one handler (bench/cli/app.py ``error_line``) prints it as one
line, exit 2, and nothing is written. A RuntimeError of any other cause stays an internal error."""

from __future__ import annotations


class SolveFailed(RuntimeError):
    """A solver stopped without a solution; ``stats`` holds what it reported (status, iterations)."""

    def __init__(self, message: str, stats: dict | None = None) -> None:
        super().__init__(message)
        self.stats = dict(stats or {})


__all__ = ["SolveFailed"]
