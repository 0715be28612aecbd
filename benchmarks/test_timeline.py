"""A pytest plugin for benchmarks/test_suite.py ``--timeline``: when each test
started and ended, per test process.

Loaded with ``-p test_timeline`` in the usual run (every core, pytest-xdist): each test process (``gw0``,
``gw1``, ...) appends ``start end nodeid`` lines (Unix times) to ``$TEST_TIMELINE_DIR/<process>.txt``. Beside
the machine's busy share second by second, they show which files ran side by side when cores stood idle.
"""

from __future__ import annotations

import os
import time

import pytest


def _file():
    name = os.environ.get("PYTEST_XDIST_WORKER", "main")
    return open(os.path.join(os.environ["TEST_TIMELINE_DIR"], f"{name}.txt"), "a")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Setup, call and teardown of one test, as one span."""
    started = time.time()
    yield
    with _file() as f:
        f.write(f"{started:.2f} {time.time():.2f} {item.nodeid}\n")
