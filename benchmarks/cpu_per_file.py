"""A pytest plugin: each test file's CPU seconds, for ``benchmarks/suite_cost.py``.

    SUITE_COST_DIR=DIR pytest -p cpu_per_file ...   (benchmarks/ on PYTHONPATH)

Around each test (setup, call and teardown, so a module-scoped fixture counts for the file
whose first or last test runs it) it reads :func:`resource.getrusage` of the process and of
its waited-for children (worker processes, the ``workbench`` commands a test runs), and adds
the difference to the test's file, with the wall seconds and the outcome. Each process (an
xdist worker, or pytest itself without xdist) writes ``DIR/<worker>.json`` at its end:
``{file: {"cpu_s", "wall_s", "tests", "failed"}}``. A session-scoped fixture counts for the
file of the first test that uses it, once per worker.
"""

from __future__ import annotations

import json
import os
import resource
import time
from pathlib import Path

import pytest

_FILES: dict[str, dict[str, float]] = {}


def _cpu() -> float:
    total = 0.0
    for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN):
        usage = resource.getrusage(who)
        total += usage.ru_utime + usage.ru_stime
    return total


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    entry = _FILES.setdefault(item.nodeid.split("::")[0],
                              {"cpu_s": 0.0, "wall_s": 0.0, "tests": 0, "failed": 0})
    cpu, wall = _cpu(), time.perf_counter()
    yield
    entry["cpu_s"] += _cpu() - cpu
    entry["wall_s"] += time.perf_counter() - wall
    entry["tests"] += 1


def pytest_runtest_logreport(report):
    if report.failed and report.nodeid.split("::")[0] in _FILES:
        _FILES[report.nodeid.split("::")[0]]["failed"] += 1


def pytest_sessionfinish(session):
    folder = os.environ.get("SUITE_COST_DIR")
    if not folder:
        return
    worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
    Path(folder, f"{worker}.json").write_text(json.dumps(_FILES, indent=1) + "\n")
