"""``exo-bench``, the command line: one module per subcommand (:data:`~exo_bench.bench.cli.app.SUBCOMMANDS`),
assembled by :mod:`exo_bench.bench.cli.app`, whose :func:`main` is the console script."""

from exo_bench.bench.cli.app import main

__all__ = ["main"]
