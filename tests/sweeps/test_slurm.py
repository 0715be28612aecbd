"""Sweeps through a real single-node Slurm (tests/support/slurm.py): workers go out as sbatch
jobs, a cancelled job is replaced, a job Slurm refuses stops the submit with Slurm's own words,
and ``min_workers``/``max_workers`` scale the jobs through Dask's adapt. Real Slurm, real Dask,
real Parquet: nothing is mocked.

Skipped, with the reason, where Slurm cannot start (not root, or Debian's packages absent: .ci/install adds
them). The module shares one Slurm; each test leaves no job behind."""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

import dask
import pandas as pd
import pytest
from conftest import SCENARIOS, dse_runner, sleeper_multimodel, write_space

from dse_runner.errors import DseError
from dse_runner.sweeps import store
from dse_runner.sweeps.cluster import connect
from dse_runner.sweeps.makers import Cluster
from dse_runner.sweeps.spec import load_space
from dse_runner.sweeps.sweep import load_status, submit

pytestmark = pytest.mark.slow

TASKS = 12  # write_space's: 6 points x 2 scenarios


@pytest.fixture(scope="module")
def slurm(tmp_path_factory):
    from support.slurm import SingleNodeSlurm, why_not

    reason = why_not()
    if reason:
        pytest.skip(reason)
    cluster = SingleNodeSlurm(tmp_path_factory.mktemp("slurm"))
    old = os.environ.get("SLURM_CONF")
    os.environ["SLURM_CONF"] = str(cluster.conf)  # for sbatch, squeue and scancel, here and in dse-runner
    yield cluster
    if old is None:
        os.environ.pop("SLURM_CONF", None)
    else:
        os.environ["SLURM_CONF"] = old
    cluster.close()
    assert not cluster.leftovers(), "a Slurm daemon or job process outlived the cluster"


@pytest.fixture
def no_job_left(slurm):
    """Every test ends with no job queued or running: the sweep gave its jobs back."""
    yield
    slurm.wait_for_no_jobs(60)


def slurm_block(tmp_path: Path, **options) -> dict:
    return {"cores": 1, "memory": "1GiB", "log_directory": str(tmp_path / "logs"), **options}


def raw_task_ids(output: Path) -> pd.Series:
    """Every task id in every result file, without the readers' de-duplication."""
    files = list((output / "results").rglob("part-*.parquet"))
    if not files:
        return pd.Series([], dtype=str)
    return pd.concat(pd.read_parquet(f, columns=["task_id"]) for f in files)["task_id"]


def test_a_sweep_through_sbatched_workers_lands_every_row_once(tmp_path, slurm, no_job_left):
    """`dse-runner submit` with cluster.kind slurm, as a user runs it: two worker jobs, every row once, the
    dashboard link printed on loopback, where the dashboard listens."""
    before = set(slurm.ever())
    spec = write_space(tmp_path, cluster={"kind": "slurm", "n_workers": 2, "slurm": slurm_block(tmp_path)})
    result = dse_runner("submit", spec, "--json")  # with the dashboard: --no-dashboard prints no address
    assert result.returncode == 0, result.stderr
    ids = raw_task_ids(tmp_path / "out")
    assert len(ids) == TASKS and ids.is_unique
    jobs = set(slurm.ever()) - before
    assert len(jobs) == 2, jobs  # n_workers 2 at 1 core a job
    assert all((tmp_path / "logs" / f"dask-worker-{job}.err").exists() for job in jobs)  # each job ran
    [link] = re.findall(r"Dask dashboard: (\S+)", result.stderr)
    assert link.startswith("http://127.0.0.1:"), link


def test_a_cancelled_worker_job_is_replaced(tmp_path, slurm, no_job_left):
    """scancel of one of two worker jobs mid-sweep: another job is submitted in its place, its worker
    joins, and the sweep ends with every row exactly once."""
    # a sleeper FMU: ~1 s a simulation that sleeps rather than computes, 36 of them in one-task chunks
    space = load_space(
        write_space(
            tmp_path,
            multimodel=str(sleeper_multimodel(tmp_path)),
            scenarios=[str(SCENARIOS / "*")],
            parameters={"sleeper.pause": [0.0005, 0.0006, 0.0007]},
            keep_trajectories=0,
            chunk_seconds=0.5,
            cluster={"kind": "slurm", "n_workers": 2, "slurm": slurm_block(tmp_path)},
        )
    )
    before = set(slurm.ever())
    cancelled: list[str] = []

    def cancel_one(report) -> None:
        running = slurm.running()
        if not cancelled and report.chunks >= 2 and len(running) == 2:
            slurm.cancel(running[0])
            cancelled.append(running[0])

    with dask.config.set(
        {"distributed.deploy.lost-worker-timeout": "2s"}
    ):  # how long a job's workers may be gone
        report = submit(space, progress=cancel_one)
    assert cancelled, "the sweep ended before a job could be cancelled"
    assert (report.ok, report.failed) == (36, 0), report.errors
    ids = raw_task_ids(space.output)
    assert len(ids) == 36 and ids.is_unique
    jobs = set(slurm.ever()) - before
    first = set(sorted(jobs, key=int)[:2])
    assert cancelled[0] in first
    replacements = jobs - first
    assert replacements, f"no job replaced {cancelled[0]} (jobs: {sorted(jobs)})"
    assert any((tmp_path / "logs" / f"dask-worker-{job}.err").exists() for job in replacements)  # and it ran


def test_a_job_slurm_refuses_stops_the_submit_with_slurms_reason(tmp_path, slurm, no_job_left):
    """More memory than the node has: sbatch refuses the job, and `submit` says so in one line within a
    minute (not after its 30-minute queue wait), exits non-zero, and keeps the rows it had."""
    done = load_space(
        write_space(
            tmp_path,
            parameters={"vehicle.cAlphaF": [20000], "vehicle.mass": [1000, 2000]},
            cluster={"n_workers": 1},
        )
    )
    assert submit(done).ok == 4  # finished earlier on the local cluster
    kept = set(raw_task_ids(done.output))
    spec = write_space(
        tmp_path,
        cluster={"kind": "slurm", "n_workers": 2, "slurm": slurm_block(tmp_path, memory="100000GiB")},
    )
    started = time.monotonic()
    result = dse_runner("submit", spec, "--no-dashboard")
    assert time.monotonic() - started < 60
    assert result.returncode == 2, result.stderr
    errors = [line for line in result.stderr.splitlines() if line.startswith("error:")]
    assert errors == [
        (
            "error: Slurm refused a worker job: Memory specification can not be satisfied; Batch job "
            "submission failed: Requested node configuration is not available"
        )
    ], result.stderr
    assert "Traceback" not in result.stderr
    assert set(raw_task_ids(done.output)) == kept  # nothing lost, nothing added
    assert load_status(done.output, "small").state == "failed"


def test_a_refused_replacement_stops_the_sweep_and_keeps_its_rows(tmp_path, slurm, no_job_left):
    """Mid-sweep, a job ends and Slurm refuses its replacement (the partition was made inactive): the sweep
    stops with Slurm's words, and every chunk that finished is in the store, once."""
    space = load_space(
        write_space(
            tmp_path,
            multimodel=str(sleeper_multimodel(tmp_path)),
            scenarios=[str(SCENARIOS / "*")],
            parameters={"sleeper.pause": [0.0005, 0.0006, 0.0007]},
            keep_trajectories=0,
            chunk_seconds=0.5,
            cluster={"kind": "slurm", "n_workers": 2, "slurm": slurm_block(tmp_path)},
        )
    )
    closed: list[str] = []

    def close_the_partition(report) -> None:
        running = slurm.running()
        if not closed and report.chunks >= 2 and len(running) == 2:
            slurm.run("scontrol", "update", "PartitionName=debug", "State=INACTIVE")
            slurm.cancel(running[0])
            closed.append(running[0])

    try:
        with (
            dask.config.set({"distributed.deploy.lost-worker-timeout": "2s"}),
            pytest.raises(DseError, match=r"^Slurm refused a worker job: .*Required partition not available"),
        ):
            submit(space, progress=close_the_partition)
    finally:
        slurm.run("scontrol", "update", "PartitionName=debug", "State=UP")
    ids = raw_task_ids(space.output)
    assert 2 <= len(ids) < 36 and ids.is_unique
    assert len(store.read_results(space.output, "small", columns=[])) == len(ids)


def test_adaptive_scaling_starts_jobs_for_waiting_tasks_and_gives_them_back(tmp_path, slurm, no_job_left):
    """cluster min_workers 0, max_workers 2: a sweep starts from no job and lands every row once; on the same
    kind of cluster, a queue of tasks brings up to two jobs, and they are given back once it empties."""
    adaptive = {"kind": "slurm", "min_workers": 0, "max_workers": 2, "slurm": slurm_block(tmp_path)}
    report = submit(load_space(write_space(tmp_path, cluster=adaptive)))
    assert (report.ok, report.failed) == (TASKS, 0), report.errors
    ids = raw_task_ids(tmp_path / "out")
    assert len(ids) == TASKS and ids.is_unique
    slurm.wait_for_no_jobs(60)

    most = 0
    with connect(Cluster.model_validate(adaptive)) as client:
        assert slurm.jobs() == []  # nothing waits: no job
        futures = client.map(time.sleep, [1.0] * 20, pure=False)  # 20 s of work: Dask asks for two workers
        while not all(f.done() for f in futures):
            most = max(most, len(slurm.jobs()))
            time.sleep(0.5)
        assert most == 2
        client.gather(futures)
        del futures  # Dask keeps a worker that holds results the client still refers to
        deadline = time.monotonic() + 60
        while slurm.jobs():  # the queue is empty: adapt retires the workers and their jobs are cancelled
            assert time.monotonic() < deadline, (
                f"jobs still held 60 s after the queue emptied: {slurm.jobs()}"
            )
            time.sleep(0.5)
        assert not client.scheduler_info()["workers"]
