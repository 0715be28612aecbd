"""A user's clone has nothing beside it: no ../shared. The README's test command must still pass there: the
tests that need shared material skip with a reason, and no test file errors at collection."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _clone(folder: Path) -> Path:
    """The checkout's tracked tests, jobs, scenarios and pytest settings, as they are in the working tree,
    copied into ``folder`` (whose parent has no shared/)."""
    listed = subprocess.run(
        ["git", "ls-files", "tests", "jobs", "scenarios", "pyproject.toml"],
        check=False,
        cwd=REPO,
        capture_output=True,
        text=True,
    )
    if listed.returncode != 0:
        pytest.skip(f"not a git checkout ({listed.stderr.strip()}): nothing to clone")
    for name in listed.stdout.split():
        source, target = REPO / name, folder / name
        if source.is_file():
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target)
    return folder


@pytest.mark.slow  # collects the whole suite in a process of its own
def test_a_clone_without_shared_collects_everything_and_skips_what_needs_shared(tmp_path):
    clone = _clone(tmp_path / "clone")
    assert not (clone.parent / "shared").exists()
    pytest_in_clone = [sys.executable, "-m", "pytest", "-n0", "-p", "no:cacheprovider"]
    collected = subprocess.run(
        [*pytest_in_clone, "--collect-only", "-q"],
        check=False,
        cwd=clone,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert collected.returncode == 0, collected.stdout[-3000:] + collected.stderr[-2000:]
    assert "error" not in collected.stdout.splitlines()[-1]
    ran = subprocess.run(
        [
            *pytest_in_clone,
            "-q",
            "-rs",
            "tests/simulation/test_wild_fmus.py",
            "tests/analysis/test_real_recordings.py::test_the_job_holds_the_published_files_unchanged",
        ],
        check=False,
        cwd=clone,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert ran.returncode == 0, ran.stdout[-3000:]
    assert " passed" not in ran.stdout.splitlines()[-1] and "skipped" in ran.stdout.splitlines()[-1]
    assert "is not beside the checkout" in ran.stdout and "is not beside this checkout" in ran.stdout
