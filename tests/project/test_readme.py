"""The README's Python example runs as written, from a folder laid out as the checkout is."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import pytest
from conftest import REPO


def python_blocks(text: str) -> list[str]:
    return re.findall(r"```python\n(.*?)```", text, flags=re.DOTALL)


@pytest.mark.slow  # the README's calibration, on a local cluster
def test_the_readmes_python_example_runs_as_written(tmp_path):
    (block,) = python_blocks((REPO / "README.md").read_text())
    # The files it names, its results kept out of the checkout: the space copied
    # (its output is relative to it).
    (tmp_path / "jobs" / "robotti").mkdir(parents=True)
    shutil.copy(REPO / "jobs" / "robotti" / "space.yaml", tmp_path / "jobs" / "robotti")
    (tmp_path / "jobs" / "watertank").symlink_to(REPO / "jobs" / "watertank")
    (tmp_path / "scenarios").symlink_to(REPO / "scenarios")
    script = tmp_path / "example.py"
    script.write_text(block)
    done = subprocess.run(
        [sys.executable, str(script)], check=False, cwd=tmp_path, capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert re.search(r"vehicle\.cAlphaF", done.stdout), done.stdout  # the best point, printed
    assert (tmp_path / "out" / "robotti-calibration").is_dir()


def test_the_readmes_table1_is_laid_out_as_the_cli_prints_it(capsys):
    """The README's "What the main job prints" shows Table 1 as `submit` prints it: the CLI, given the block's
    own figures, prints the block line for line (its title, column names, widths and the best point)."""
    import pandas as pd

    from dse_runner.interfaces.cli import _print_table1
    from dse_runner.sweeps.rank import Ranking

    text = (REPO / "README.md").read_text()
    block = [line.removeprefix("    ") for line in text[text.index("    Table 1: ") :].splitlines()]
    block = block[: next(i for i, line in enumerate(block) if line.startswith("best: ")) + 1]
    rows = [line.split() for line in block[2:-1]]
    table1 = pd.DataFrame(
        [
            {
                "scenario": r[0],
                "group": "",
                **dict(
                    zip(
                        ("min_error", "max_error", "average_error", "computed", "difference"),
                        map(float, r[1:]),
                    )
                ),
            }
            for r in rows
        ]
    )
    points = int(re.search(r"\((\d+) points\)", block[0])[1])
    best = {name: float(value) for name, value in re.findall(r"(\S+) = ([\d.]+)", block[-1])}
    total = float(re.search(r"cross_track_error ([\d.]+)\)", block[-1])[1])
    none = pd.DataFrame()
    _print_table1(
        Ranking(
            "robotti-calibration",
            list(best),
            "cross_track_error",
            "min",
            best,
            total,
            pd.DataFrame(index=range(points)),
            table1,
            none,
            none,
            none,
            0,
            0,
        )
    )
    assert capsys.readouterr().out.splitlines() == block
