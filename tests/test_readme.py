"""The README's Python example runs as written, from a folder laid out as the checkout is."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

from conftest import REPO


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_the_readmes_python_example_runs_as_written(tmp_path):
    (block,) = python_blocks((REPO / "README.md").read_text())
    # The files it names, its results kept out of the checkout: the space copied (its output is relative to it).
    (tmp_path / "jobs" / "robotti").mkdir(parents=True)
    shutil.copy(REPO / "jobs" / "robotti" / "space.yaml", tmp_path / "jobs" / "robotti")
    (tmp_path / "jobs" / "watertank").symlink_to(REPO / "jobs" / "watertank")
    (tmp_path / "scenarios").symlink_to(REPO / "scenarios")
    script = tmp_path / "example.py"
    script.write_text(block)
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    assert re.search(r"vehicle\.cAlphaF", done.stdout), done.stdout  # the best point, printed
    assert (tmp_path / "out" / "robotti-calibration").is_dir()
