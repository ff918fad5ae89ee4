"""The two ways the tests run ``exo-bench``: :func:`run_cli` in this process (fast; a monkeypatch
reaches the code it runs) and :func:`cli_process` in a fresh one (what a shell sees: the exit status,
the whole stdout and stderr, the process's own environment and imports)."""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys

from exo_bench.bench.cli import app as cli

#: The command line of ``exo-bench`` in a fresh process of this interpreter.
EXO_BENCH = [sys.executable, "-m", "exo_bench.bench.cli"]


def run_cli(argv: list) -> tuple[int, str, str]:
    """``exo-bench argv`` in this process (each argument as ``str``): (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cli.main([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue()


def cli_process(*args, timeout: float = 600, **kw) -> subprocess.CompletedProcess:
    """``exo-bench args`` (each as ``str``) in a fresh process, stdout and stderr captured as text;
    ``timeout`` is a safety net that never decides a pass; ``kw``: :func:`subprocess.run`'s (cwd, env)."""
    return subprocess.run([*EXO_BENCH, *map(str, args)], capture_output=True, text=True, timeout=timeout, **kw)


def main_job(reports, *scenes) -> int:
    """``exo-bench run SCENES... --reports REPORTS`` in this process (the main job, with no ``--full``):
    its exit code."""
    from exo_bench.bench.cli.run import run_main_job
    from exo_bench.bench.studies.options import RunOptions

    return run_main_job(RunOptions(scenes=tuple(str(s) for s in scenes), reports=str(reports)))
