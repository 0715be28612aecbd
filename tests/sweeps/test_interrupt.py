"""Ctrl-C during ``dse-runner submit``: one line on stderr, exit code 130, and a count that is on disk.

A terminal sends SIGINT to its whole foreground process group: the client and the worker processes of
the local cluster it started. These tests do the same (the submit in a session of its own, SIGINT to its
group) to a real ``submit`` on a real local cluster of two worker processes, and then submit again.

The sleeper FMU sleeps ``pause`` seconds of wall time in every step, so a task on sin1 (1680 steps)
lasts at least 1680 x pause however idle or busy the machine is: once a first row is on disk, several
rounds of tasks remain, and the interrupt lands mid-sweep without the test guessing a delay."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
import psutil
import pytest
from conftest import REPO, SCENARIOS, sleeper_multimodel, strict_loads, write_space, write_yaml

from dse_runner.sweeps import store

pytestmark = pytest.mark.slow  # Ctrl-C sent to the command's process group mid-sweep on a local cluster

PAUSE = 0.002  # s slept per step: a task takes 3.4 s or more
TASKS = 8  # points of the grid, one scenario each: four rounds on two workers
NOT_THE_LINE = ("dse-runner dashboard: ", "linked from Dask's dashboard: ", "Dask dashboard: ")


def grid(folder: Path) -> Path:
    """Eight points of the sleeper on sin1, a task a chunk, on a local cluster of two workers."""
    return write_space(
        folder,
        multimodel=str(sleeper_multimodel(folder)),
        scenarios=[str(SCENARIOS / "sin1")],
        parameters={"sleeper.pause": [PAUSE + k * 1e-5 for k in range(TASKS)]},
        keep_trajectories=0,
        chunk_seconds=0.05,
        cluster={"n_workers": 2},
    )


def search(folder: Path) -> Path:
    """A seeded random search of eight points over the sleeper's pause, on the same cluster."""
    return write_yaml(
        folder,
        {
            "name": "small",
            "multimodel": str(sleeper_multimodel(folder)),
            "scenarios": [str(SCENARIOS / "sin1")],
            "parameters": {"sleeper.pause": {"low": PAUSE, "high": 1.1 * PAUSE}},
            "search": {"strategy": "random", "max_points": TASKS, "seed": 1},
            "output": str(folder / "out"),
            "keep_trajectories": 0,
            "cluster": {"n_workers": 2},
        },
    )


def start(spec: Path, *options: str) -> subprocess.Popen:
    """``dse-runner submit`` in a session of its own: a process group of its own, as in a
    terminal, with Ctrl-C's signal at its default (a test runner's worker may ignore it, and
    an ignored SIGINT is inherited)."""
    return subprocess.Popen(
        [sys.executable, "-m", "dse_runner", "submit", str(spec), *options],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # noqa: PLW1509  (only that)
    )


def ctrl_c_when(
    process: subprocess.Popen, ready: Callable[[], bool], timeout: float = 300
) -> tuple[str, str]:
    """Once ``ready()``, SIGINT to the process group, as Ctrl-C in a terminal; then its stdout and stderr."""
    deadline = time.monotonic() + timeout
    while not ready():
        assert process.poll() is None, f"submit ended before it could be interrupted: {process.communicate()}"
        assert time.monotonic() < deadline, "never ready to be interrupted"
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGINT)
    return process.communicate(timeout=600)


def rows_on_disk(folder: Path) -> Callable[[], bool]:
    return lambda: any((folder / "out" / "results").rglob("part-*.parquet"))


def the_one_line(stderr: str) -> str:
    """Ctrl-C's line. Besides it, stderr holds only the dashboards' addresses and the progress bar: no
    traceback and no error, from the client, a worker process or Dask's logging."""
    assert not re.search(r"traceback|error|exception|warning", stderr, re.IGNORECASE), stderr
    lines = [
        line
        for line in stderr.splitlines()
        if line.strip() and not line.startswith(NOT_THE_LINE) and "sim/s" not in line
    ]
    assert len(lines) == 1, stderr
    return lines[0]


def counted(line: str) -> tuple[int, int]:
    match = re.fullmatch(
        r"interrupted: (\d+) of (\d+) tasks have results in (.+); "
        r"run the same command again to finish the rest",
        line,
    )
    assert match, line
    return int(match[1]), int(match[2])


def command_line(process: psutil.Process) -> list[str]:
    """Its command line; none if it has ended meanwhile."""
    try:
        return process.cmdline()
    except psutil.Error:
        return []


def rows(folder: Path) -> int:
    return len(store.read_results(folder / "out", "small", columns=[]))


@dataclass
class Interrupted:
    """A grid sweep Ctrl-C'd once its first rows were on disk, then submitted again with --json."""

    folder: Path
    returncode: int
    out: str
    err: str
    rows: int  # rows on disk after the interrupt
    partial: list[Path]  # half-written files left visible after the interrupt
    kept: dict[Path, int]  # each result file after the interrupt -> its mtime (ns)
    again: subprocess.CompletedProcess
    scratch: Path  # TMPDIR of the second submission


@pytest.fixture(scope="module")
def interrupted(tmp_path_factory) -> Interrupted:
    """One interrupted sweep and its second submission, which the two tests below check from both sides (the
    command's one line and count; the store's files): a sweep of 3.4 s tasks, made once."""
    folder = tmp_path_factory.mktemp("interrupted")
    spec = grid(folder)
    first = start(spec)
    out, err = ctrl_c_when(first, rows_on_disk(folder))
    results = folder / "out" / "results"
    on_disk, partial = rows(folder), list((folder / "out").rglob("*.partial"))
    kept = {p: p.stat().st_mtime_ns for p in results.rglob("part-*.parquet")}
    scratch = folder / "tmp"  # the second submission's temporary folder, and its workers'
    scratch.mkdir()
    again = subprocess.run(
        [sys.executable, "-m", "dse_runner", "submit", str(spec), "--json"],
        check=False,
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "TMPDIR": str(scratch)},
    )
    return Interrupted(folder, first.returncode, out, err, on_disk, partial, kept, again, scratch)


def test_ctrl_c_mid_sweep_says_one_line_with_the_count_on_disk_and_a_rerun_finds_as_many(interrupted):
    assert interrupted.returncode == 130, interrupted.err
    assert interrupted.out == ""  # the report and Table 1 are for a finished sweep
    done, total = counted(the_one_line(interrupted.err))
    assert done == interrupted.rows and 0 < done < total == TASKS  # chunks that were running have written

    second = interrupted.again
    assert second.returncode == 0, second.stderr
    report = strict_loads(second.stdout)
    assert (report["skipped"], report["ran"], report["failed"]) == (done, TASKS - done, 0)
    assert rows(interrupted.folder) == TASKS


def test_interrupted_sweep_resumes_without_repeating_work(interrupted):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) keeps finished chunks, and no
    half-written file is left visible; submitting again runs exactly the missing tasks."""
    assert interrupted.returncode == 130 and "run the same command again" in interrupted.err
    assert 0 < interrupted.rows < TASKS and interrupted.kept
    assert not interrupted.partial

    second = interrupted.again
    assert second.returncode == 0, second.stderr
    report = strict_loads(second.stdout)
    assert report["skipped"] == interrupted.rows and report["ran"] == TASKS - interrupted.rows
    output = interrupted.folder / "out"
    after = store.read_results(output, "small", columns=[])
    assert len(after) == TASKS and after["task_id"].is_unique
    assert all(p.stat().st_mtime_ns == m for p, m in interrupted.kept.items())  # finished chunks not redone
    files = (output / "results").rglob("part-*.parquet")
    raw = pd.concat(pd.read_parquet(p, columns=["task_id"]) for p in files)
    assert len(raw) == TASKS  # every task exactly once on disk, not merely after de-duplication


def test_a_finished_submit_leaves_no_temporary_folder(interrupted):
    """The client and every worker extract FMUs and unpack the shipment into folders of their own, which
    each removes when it exits: a day of sweeps used to leave thousands in /tmp."""
    assert interrupted.again.returncode == 0, interrupted.again.stderr
    assert sorted(p.name for p in interrupted.scratch.iterdir() if p.name.startswith("dse-runner-")) == []


def test_ctrl_c_while_the_cluster_starts_says_one_line(tmp_path):
    """The worker processes get the SIGINT while they start up; none of them says anything."""
    spec = grid(tmp_path)
    first = start(spec, "--json")

    def workers_starting() -> bool:
        """A worker exists: spawned, or forked by the command's forkserver (its line is the server's)."""
        children = psutil.Process(first.pid).children(recursive=True)
        lines = [" ".join(command_line(child)) for child in children]
        forked = sum("multiprocessing.forkserver" in line for line in lines) > 1  # the server and a worker
        return forked or any("spawn_main" in line for line in lines)

    out, err = ctrl_c_when(first, workers_starting)
    assert first.returncode == 130, err
    assert out == ""  # --json: no object for an interrupted submit, and nothing else on stdout
    assert counted(the_one_line(err)) == (rows(tmp_path), TASKS)


def test_ctrl_c_mid_search_says_one_line_with_the_count_on_disk_and_a_rerun_goes_on(tmp_path):
    spec = search(tmp_path)
    first = start(spec, "--json")
    out, err = ctrl_c_when(first, rows_on_disk(tmp_path))
    assert first.returncode == 130, err
    assert out == ""
    done, budget = counted(the_one_line(err))
    assert done == rows(tmp_path) and 0 < done < budget == TASKS

    second = subprocess.run(
        [sys.executable, "-m", "dse_runner", "submit", str(spec), "--json"],
        check=False,
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert second.returncode == 0, second.stderr
    found = strict_loads(second.stdout)["search"]
    assert (found["points"], found["reused"], found["stopped"]) == (TASKS, done, "budget")
    assert rows(tmp_path) == TASKS
