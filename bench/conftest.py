"""pytest-benchmark configuration: the sweep profile, a record of skipped rows with reasons, and the
rows of the distributed sweep (``--row KEY``, ``--rows-json PATH``: bench/perf/rows.py)."""

from __future__ import annotations

import json

import pytest

from exo_bench.bench.perf import rows as _rows
from exo_bench.bench.perf import profiles as _sweep

_SKIPS: list[dict] = []


def pytest_addoption(parser):
    parser.addoption("--sweep", default=None, help="benchmark profile: quick (default) or full")
    parser.addoption("--skips-json", default=None, help="write skipped benchmark rows and reasons to this file")
    _rows.add_options(parser)


def pytest_collection_modifyitems(session, config, items):
    _rows.select(config, items, _sweep.current(config.getoption("--sweep")).name)


def pytest_benchmark_update_json(config, benchmarks, output_json):
    _rows.record_peak_memory(config, output_json)


@pytest.fixture(scope="session")
def sweep(request) -> _sweep.Sweep:
    return _sweep.current(request.config.getoption("--sweep"))


def pytest_runtest_logreport(report):
    if report.skipped and report.when in ("setup", "call"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        _SKIPS.append(
            {
                "nodeid": report.nodeid,
                "reason": reason.removeprefix("Skipped: "),
                "params": getattr(report, "user_properties", []),
            }
        )


def pytest_sessionfinish(session, exitstatus):
    path = session.config.getoption("--skips-json")
    if path:
        from exo_bench.models.files import atomic_write

        atomic_write(path, json.dumps(_SKIPS, indent=1))
