"""Running a design space on Dask: chunks of tasks in, Parquet partitions out.

The client expands the space lazily, skips tasks that already have a row,
and keeps a bounded number of chunks in flight. Each chunk runs on a worker
(:func:`run_chunk`), which simulates its tasks with the worker's cached FMU
instances, writes the rows itself and returns only a small summary, so the
client's memory does not grow with the sweep. A failing simulation becomes a
failed row after one retry; it never stops the sweep. Interrupting leaves
every finished chunk on disk; submitting again finishes the rest.
"""

from __future__ import annotations

import hashlib
import math
import os
import socket
import time
import traceback
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa

from . import store
from .cluster import connect, total_threads
from .cosim import Plan, make_plan
from .errors import DseError
from .expand import Task, TaskBatch, chunked, expand, model_hash, points_of
from .multimodel import MultiModel
from .rank import rank, save_sweep_spec
from .scenario import Scenario
from .search import Point
from .simulate import simulate
from .spec import Space

ATTEMPTS = 2  # a failing simulation is retried once


@dataclass(frozen=True)
class ChunkJob:
    """Everything a worker needs for one chunk; small, picklable."""

    sweep: str
    chunk_id: str
    model_key: str
    multimodel: MultiModel
    scenarios: dict[str, Scenario]
    tasks: TaskBatch
    objectives: tuple[str, ...]
    output: Path
    schema: pa.Schema
    timeout: float


@dataclass
class ChunkSummary:
    chunk_id: str
    ok: int
    failed: int
    seconds: float  # wall time of the simulations
    errors: list[str] = field(default_factory=list)  # first few failure messages


_PLANS: dict[str, Plan] = {}


def _plan(model_key: str, multimodel: MultiModel) -> Plan:
    """One plan per model per worker process."""
    plan = _PLANS.get(model_key)
    if plan is None:
        plan = _PLANS[model_key] = make_plan(multimodel)
    return plan


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().name)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def run_task(plan: Plan, task: Task, scenario: Scenario, objectives: tuple[str, ...],
             timeout: float) -> tuple[dict[str, float] | None, str | None]:
    """Objectives, or the error message after the retry."""
    error = None
    for _ in range(ATTEMPTS):
        try:
            result = simulate(plan, scenario, dict(task.point), objectives, timeout=timeout)
            return result.objectives, None
        except DseError as e:
            error = str(e)
        except Exception as e:  # a bug or an FMU misbehaving in a way we did not foresee
            error = f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=3)}"
    return None, error


def run_chunk(job: ChunkJob) -> ChunkSummary:
    """Simulate a chunk on a worker and write its rows; return only counts."""
    plan = _plan(job.model_key, job.multimodel)
    worker, rows, errors = _worker_name(), [], []
    started = time.perf_counter()
    for task in job.tasks:
        scenario = job.scenarios[task.scenario]
        t0 = time.perf_counter()
        scores, error = run_task(plan, task, scenario, job.objectives, job.timeout)
        if error and len(errors) < 3:
            errors.append(f"{task.scenario} {dict(task.point)}: {error}")
        rows.append({
            "task_id": task.task_id, "model": job.model_key, "scenario": task.scenario, "group": scenario.group,
            **dict(task.point),
            **(scores or {name: None for name in job.objectives}),
            "status": "ok" if error is None else "failed", "error": error,
            "wall_time": time.perf_counter() - t0, "worker": worker,
        })
    seconds = time.perf_counter() - started
    store.write_rows(job.output, job.sweep, job.chunk_id, rows, job.schema)
    failed = sum(r["status"] == "failed" for r in rows)
    return ChunkSummary(job.chunk_id, len(rows) - failed, failed, seconds, errors)


@dataclass
class SweepReport:
    sweep: str
    output: Path
    total: int  # tasks in the space
    skipped: int  # already had a row
    ok: int = 0
    failed: int = 0
    seconds: float = 0.0  # wall time of this submission
    simulation_seconds: float = 0.0  # summed on the workers
    chunk_size: int = 0
    chunks: int = 0
    workers: int = 0
    dashboard: str | None = None
    interrupted: bool = False
    errors: list[str] = field(default_factory=list)

    @property
    def ran(self) -> int:
        return self.ok + self.failed


Progress = Callable[[SweepReport], None]


def probe_seconds(space: Space, points: list[Point] | None = None) -> float | None:
    """Time one simulation in the client to size chunks; None if it failed (that point
    will fail on a worker too and become a failed row, which must not stop the sweep)."""
    point = next(iter(points_of(space, points)(space)), None)
    if point is None:
        raise DseError(f"{space.path}: the constraints exclude every parameter point")
    start = time.perf_counter()
    try:
        simulate(space.plan, space.scenarios[0], point, space.objectives, timeout=space.spec.timeout)
    except Exception:
        return None
    return time.perf_counter() - start


UNKNOWN_TASK_SECONDS = 0.1  # when the probe failed: a guess that keeps chunks small


def chunk_size(seconds_per_task: float | None, target_seconds: float, pending: int, threads: int) -> int:
    """Tasks per chunk: long enough that Dask's per-task cost (~ms) is under 1-5% of the
    chunk, short enough that every thread gets several chunks to balance the load."""
    per_task = UNKNOWN_TASK_SECONDS if seconds_per_task is None else max(seconds_per_task, 1e-6)
    by_time = max(1, round(target_seconds / per_task))
    by_balance = max(1, math.ceil(pending / (4 * threads)))
    return min(by_time, by_balance)


def _chunk_id(tasks: list[Task]) -> str:
    return hashlib.sha256("".join(t.task_id for t in tasks).encode()).hexdigest()[:20]


def submit(space: Space, progress: Progress | None = None, client=None,
           points: list[Point] | None = None) -> SweepReport:
    """Run every task of ``space`` that has no row yet; returns counts, never raises on failed tasks.

    ``points`` replaces the space's search strategy with a given list: how an
    optimiser (fit.py) runs each of its rounds as a sweep into the same store."""
    started = time.perf_counter()
    output = space.output
    save_sweep_spec(output, space.spec, model_hash(space.plan, space.objectives))
    done = store.finished_task_ids(output, space.name)
    total = skipped = 0
    for task in expand(space, points):
        total += 1
        skipped += task.task_id in done
    report = SweepReport(space.name, output, total, skipped)
    pending = total - skipped
    if pending == 0 and _trajectories_kept(space):
        report.seconds = time.perf_counter() - started
        return report
    per_task = probe_seconds(space, points) if pending else None
    if client is None:
        with connect(space.spec.cluster) as own:
            return _run(space, own, done, per_task, pending, report, progress, started, points)
    return _run(space, client, done, per_task, pending, report, progress, started, points)


def _trajectories_kept(space: Space) -> bool:
    wanted = space.spec.keep_trajectories
    return not wanted or all(
        (store.partition_dir(space.output, store.TRAJECTORIES, space.name, s.name) / f"rank-{wanted}.parquet").is_file()
        for s in space.scenarios)


def _run(space: Space, client, done: set[str], per_task: float | None, pending: int,
         report: SweepReport, progress: Progress | None, started: float, points: list[Point] | None) -> SweepReport:
    from distributed import as_completed

    threads = total_threads(client)
    report.workers = len(client.scheduler_info()["workers"])
    report.dashboard = client.dashboard_link
    report.chunk_size = chunk_size(per_task, space.spec.chunk_seconds, pending, threads) if pending else 0
    jobs = _jobs(space, done, report.chunk_size, points)
    in_flight = as_completed()
    try:
        for job in _take(jobs, 2 * threads + 2):
            in_flight.add(client.submit(run_chunk, job, key=f"chunk-{job.chunk_id}", pure=False))
        if progress:
            progress(report)
        for future in in_flight:
            summary: ChunkSummary = future.result()
            report.ok += summary.ok
            report.failed += summary.failed
            report.chunks += 1
            report.simulation_seconds += summary.seconds
            report.errors.extend(summary.errors[: max(0, 5 - len(report.errors))])
            report.seconds = time.perf_counter() - started
            for job in _take(jobs, 1):
                in_flight.add(client.submit(run_chunk, job, key=f"chunk-{job.chunk_id}", pure=False))
            if progress:
                progress(report)
    except KeyboardInterrupt:
        report.interrupted = True
        for future in list(in_flight.futures):
            future.cancel()
    if not report.interrupted and space.spec.keep_trajectories:
        keep_trajectories(space, client, space.spec.keep_trajectories)
    report.seconds = time.perf_counter() - started
    return report


def _trajectory(multimodel: MultiModel, model_key: str, scenario: Scenario, point: dict[str, Any],
                output: Path, sweep: str, place: int) -> Path:
    result = simulate(_plan(model_key, multimodel), scenario, point, objectives=())
    frame = pd.DataFrame(result.trajectory.values, columns=list(result.trajectory.names))
    frame.insert(0, "time", result.trajectory.time)
    for name, value in point.items():
        frame[f"point:{name}"] = value
    return store.write_trajectory(output, sweep, scenario.name, place, frame)


def keep_trajectories(space: Space, client, count: int) -> list[Path]:
    """Simulate the ``count`` best points again on every scenario and keep their tracks."""
    try:
        ranking = rank(space.output, space.name)
    except DseError:
        return []  # nothing complete to rank: no best points
    key = model_hash(space.plan, space.objectives)
    best = ranking.totals.head(count)[ranking.parameters].to_dict("records")
    futures = [client.submit(_trajectory, space.multimodel, key, scenario, point, space.output, space.name,
                             place, pure=False)
               for place, point in enumerate(best, start=1) for scenario in space.scenarios]
    return client.gather(futures)


def trajectories_of(space: Space, client, point: dict[str, Any], sweep: str) -> dict[str, pd.DataFrame]:
    """Simulate one point on every scenario on the cluster, keep the tracks as ``sweep``'s rank 1,
    and return them by scenario."""
    key = model_hash(space.plan, space.objectives)
    futures = [client.submit(_trajectory, space.multimodel, key, scenario, point, space.output, sweep, 1, pure=False)
               for scenario in space.scenarios]
    client.gather(futures)
    return {s.name: store.read_trajectory(space.output, sweep, s.name) for s in space.scenarios}


def _jobs(space: Space, done: set[str], size: int, points: list[Point] | None) -> Iterator[ChunkJob]:
    key = model_hash(space.plan, space.objectives)
    schema = store.results_schema(space.parameters, space.objectives)
    scenarios = {s.name: s for s in space.scenarios}
    todo = (t for t in expand(space, points) if t.task_id not in done)
    for tasks in chunked(todo, size):
        used = {t.scenario: scenarios[t.scenario] for t in tasks}
        yield ChunkJob(space.name, _chunk_id(tasks), key, space.multimodel, used, TaskBatch.of(tasks), space.objectives,
                       space.output, schema, space.spec.timeout)


def _take(iterator: Iterator[Any], n: int) -> list[Any]:
    return [job for _, job in zip(range(n), iterator)]
