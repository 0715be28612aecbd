"""docs/quickstart.md as a new user follows it: every command run as written, in a fresh copy of the
folders it reads, printing what the page shows (docs/quickstart_page.py says how lines are compared)."""

from __future__ import annotations

import importlib.util
import shutil
import sys

import pytest
from conftest import REPO

pytestmark = pytest.mark.slow  # the page's eight steps, about two minutes


def page_module():
    spec = importlib.util.spec_from_file_location("quickstart_page", REPO / "docs" / "quickstart_page.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["quickstart_page"] = module  # its dataclass looks itself up there
    spec.loader.exec_module(module)
    return module


def test_the_quickstart_page_prints_what_it_shows():
    page = page_module()
    text = page.PAGE.read_text()
    commands = [step.command.split()[:2] for step in page.steps(text)]
    for needed in (
        ["dse-runner", "describe"],
        ["dse-runner", "simulate"],
        ["dse-runner", "submit"],
        ["dse-runner", "sensitivity"],
        ["dse-runner", "diagnose"],
        ["dse-runner", "report"],
    ):
        assert needed in commands, f"the page lost its {needed[1]} step"
    root = page.fresh_folder()
    try:
        assert page.check(text, root) == []
        assert (root / "out" / "quickstart-calibrate" / "report.html").stat().st_size > 100_000
    finally:
        shutil.rmtree(root, ignore_errors=True)


def test_the_comparison_catches_a_changed_number_or_word_and_lets_timings_differ(tmp_path):
    """The check is only as good as its comparison: a fitted value off by 10 % or a changed word fails,
    a run time or a size does not."""
    page = page_module()
    ran = "quickstart-sweep: 40 tasks, 0 already done, ran 40 simulations (0 failed)"
    shown = [f"{ran} in 2.7 s on 2 workers", "...", "best: msd.k = 16, msd.c = 6  (total settle 0.790)"]
    printed = [
        f"{ran} in 9.1 s on 2 workers",
        "Table 1: settle per scenario (40 points)",
        "best: msd.k = 16, msd.c = 6  (total settle 0.791)",
    ]

    def differences(shown_lines, printed_lines):
        return page.differences(
            [page.normal(line, tmp_path) for line in shown_lines],
            [page.normal(line, tmp_path) for line in printed_lines],
        )

    assert differences(shown, printed) == []
    assert differences([shown[0], shown[2]], printed) != []  # a line printed but neither shown nor skipped
    assert differences([shown[0], "...", "best: msd.k = 16, msd.c = 6  (total settle 0.870)"], printed) != []
    assert differences([shown[0], "...", "best: msd.k = 16, msd.c = 6  (total time 0.790)"], printed) != []
    assert differences(["report: out/r.html (1.4 MB)"], ["report: out/r.html (2.1 MB)"]) == []
    assert differences([*shown, "ranking: out/x"], printed) != []  # shown but never printed
