"""A pytest plugin for benchmarks/test_suite.py ``--by-file``: the machine's busy CPU seconds over each test.

Loaded with ``-p cpu_per_test`` in a one-process run (``-n 0``), so that what the machine spends while a test
runs is that test's: its own process, the Dask scheduler and workers it keeps busy, the commands and the
browser it starts. Writes ``[[nodeid, cpu_s, wall_s], ...]`` as JSON to ``$CPU_PER_TEST_OUT`` at the end.
"""

from __future__ import annotations

import json
import os
import time

import pytest
from test_suite import busy_jiffies

_ROWS: list[tuple[str, float, float]] = []


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Setup, call and teardown of one test, timed together."""
    busy, started = busy_jiffies()[0], time.perf_counter()
    yield
    _ROWS.append(
        (item.nodeid, (busy_jiffies()[0] - busy) / os.sysconf("SC_CLK_TCK"), time.perf_counter() - started)
    )


def pytest_sessionfinish(session) -> None:
    with open(os.environ["CPU_PER_TEST_OUT"], "w") as f:
        json.dump(_ROWS, f)
