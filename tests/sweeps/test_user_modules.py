"""A user's objective module beside the space: found without PYTHONPATH, on the client and on workers in
other processes, and not needed again by the commands that read the stored values."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import REPO, dse_runner, strict_loads

MSD = REPO / "jobs" / "msd"

SCORES = '''import numpy as np


def overshoot(trajectory, scenario):
    """How far the mass swings past rest on the other side [m]."""
    return float(-np.min(trajectory.column("msd.x")))
'''


def study(folder, address: str, source: str = SCORES):
    """A space in ``folder`` scored by ``scores:overshoot``, scores.py beside it, on the test's cluster."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "scores.py").write_text(source)
    spec = {
        "name": "own",
        "multimodel": {"fmus": {"msd": str(MSD / "fmus" / "msd")}},
        "experiment": {"stop_time": 10, "step": 0.05},
        "parameters": {"msd.k": [10, 14], "msd.c": [0.4, 0.8]},
        "objectives": {"overshoot": "scores:overshoot", "x_max": {"signal": "msd.x", "reduce": "max"}},
        "output": str(folder / "out"),
        "cluster": {"address": address},
    }
    (folder / "space.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return folder / "space.yaml"


def test_a_module_beside_the_spec_scores_on_the_workers_and_rank_and_report_do_not_import_it(
    tmp_path, dask_scheduler
):
    """Submitted from another folder (no PYTHONPATH, the workers in other processes), the function scores
    every task; with the module gone, rank and report still read the stored values. An edited module
    scores anew on the next submit."""
    space = study(tmp_path / "study", dask_scheduler)
    done = dse_runner("submit", space, "--no-dashboard", "--json")
    assert done.returncode == 0, done.stderr
    found = strict_loads(done.stdout)
    assert (found["ok"], found["failed"]) == (4, 0)

    (tmp_path / "study" / "scores.py").unlink()
    ranked = dse_runner("rank", tmp_path / "study" / "out", "--json")
    assert ranked.returncode == 0, ranked.stderr
    assert strict_loads(ranked.stdout)["objective"] == "overshoot"
    assert 0 < strict_loads(ranked.stdout)["best_total"] < 0.1  # released from 0.1 m: it swings back less
    report = dse_runner("report", tmp_path / "study" / "out", "-o", tmp_path / "report.html")
    assert report.returncode == 0, report.stderr

    (tmp_path / "study" / "scores.py").write_text(SCORES.replace("return float(", "return 2 * float("))
    again = dse_runner("submit", space, "--no-dashboard", "--json")
    assert again.returncode == 0, again.stderr
    assert strict_loads(again.stdout)["ran"] == 4  # the edited module is another model: every task anew
    assert strict_loads(dse_runner("rank", tmp_path / "study" / "out", "--json").stdout)["best_total"] == (
        pytest.approx(2 * strict_loads(ranked.stdout)["best_total"])
    )


@pytest.mark.parametrize(
    "source, named",
    [
        ("def overshoot(trajectory, scenario)\n    return 1\n", "scores.py: line 1: SyntaxError"),
        ("import numpy\n\nraise RuntimeError('no licence')\n", "scores.py: line 3: RuntimeError: no licence"),
        ("def other(trajectory, scenario):\n    return 1\n", "scores has no function 'overshoot'"),
        (  # a signature the contract cannot call: refused as the spec loads, not in every task (issue 63)
            "def overshoot(trajectory):\n    return 1\n",
            "objectives.overshoot: objective 'scores:overshoot': overshoot(trajectory) cannot be called as "
            + "an objective is, with (trajectory, scenario): too many positional arguments",
        ),
        (
            "def overshoot(trajectory, scenario, limit):\n    return 1\n",
            "overshoot(trajectory, scenario, limit) cannot be called as an objective is, with (trajectory, "
            + "scenario): missing a required argument: 'limit'",
        ),
    ],
    ids=["syntax", "raises", "no-function", "one-argument", "three-arguments"],
)
def test_a_module_that_cannot_serve_is_one_line_naming_the_file(tmp_path, source, named):
    space = study(tmp_path, "tcp://127.0.0.1:1", source)  # refused before any cluster is reached
    done = dse_runner("submit", space, "--no-dashboard")
    assert done.returncode == 2
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith("error:") and named in line, done.stderr


def test_simulate_finds_a_module_in_the_current_folder(tmp_path):
    """``simulate MODEL --objective scores:overshoot`` in the folder holding scores.py, as a user runs it."""
    (tmp_path / "scores.py").write_text(SCORES)
    shutil.copytree(MSD / "fmus" / "msd", tmp_path / "msd")
    command = Path(sys.executable).with_name("dse-runner")  # installed: -m would put the folder on sys.path
    done = subprocess.run(
        [str(command), "simulate", "msd", "--objective", "scores:overshoot", "--json"],
        check=False,
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert 0 < strict_loads(done.stdout)["objectives"]["scores:overshoot"] < 0.1
