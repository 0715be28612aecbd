"""Running a design space on Dask: chunks of tasks in, Parquet partitions out.

The client expands the space lazily, skips tasks that already have a row,
ships the FMUs and recordings to the workers (ship.py) and keeps a bounded
number of chunks in flight. Each chunk runs on a worker (:func:`run_chunk`),
which simulates its tasks with the worker's cached FMU instances, writes the
rows to the store itself and returns only a small summary, so the client's
memory does not grow with the sweep.

What can go wrong, and what happens:

- a simulation fails or diverges: a failed row after one retry; the sweep goes on;
- a worker dies (killed, out of memory): Dask runs its chunk again elsewhere;
- a chunk keeps killing workers (an FMU that segfaults): it is split in halves
  until the task that crashes is alone, and that task gets a failed row;
- the scheduler restarts: the client reconnects, re-reads the store and runs
  what is missing;
- the client is interrupted or killed: finished chunks are in the store;
  submitting again runs the rest.
"""

from __future__ import annotations

import hashlib
import math
import os
import socket
import time
import traceback
from collections import deque
from collections.abc import Callable, Collection, Iterator
from concurrent.futures import CancelledError
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import pandas as pd
import pyarrow as pa
from pydantic import BaseModel, Field

from ..analysis.rank import rank, save_sweep_spec
from ..errors import DseError
from ..simulation.cosim import Plan
from ..simulation.experiment import Experiment
from ..simulation.objectives import ObjectiveSpec
from ..simulation.run import simulate
from ..simulation.scenario import Scenario
from . import ship, store
from .cluster import connect, total_threads
from .expand import Task, TaskBatch, chunked, expand, points_of
from .search import Point
from .spec import Space

ATTEMPTS = 2  # a failing simulation is retried once
CRASH_ATTEMPTS = 2  # a lone task whose worker died under it this often (beyond Dask's own retries) has failed


@dataclass(frozen=True)
class ChunkJob:
    """Everything a worker needs for one chunk besides the shipment; small, picklable."""

    sweep: str
    chunk_id: str
    shipment: str  # key of the ship.Shipment that holds the model and recordings
    model_key: str
    tasks: TaskBatch
    objectives: dict[str, ObjectiveSpec]
    output: store.Root
    schema: pa.Schema
    timeout: float
    experiment: Experiment | None = None
    crashes: int = 0  # times Dask gave up on this chunk because workers died running it

    @property
    def key(self) -> str:
        return f"chunk-{self.chunk_id}-{self.crashes}"

    def after_crash(self) -> list["ChunkJob"]:
        """What to run after workers kept dying under this chunk: its halves, or the lone task again."""
        tasks = list(self.tasks)
        if len(tasks) == 1:
            return [replace(self, crashes=self.crashes + 1)] if self.crashes + 1 < CRASH_ATTEMPTS else []
        middle = len(tasks) // 2
        return [replace(self, chunk_id=_chunk_id(part), tasks=TaskBatch.of(part), crashes=0)
                for part in (tasks[:middle], tasks[middle:])]


@dataclass
class ChunkSummary:
    chunk_id: str
    ok: int
    failed: int
    seconds: float  # wall time of the simulations
    errors: list[str] = field(default_factory=list)  # first few failure messages


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().name)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


def run_task(plan: Plan, task: Task, scenario: Scenario, objectives: dict[str, ObjectiveSpec],
             timeout: float, experiment: Experiment | None = None) -> tuple[dict[str, float] | None, str | None]:
    """Objectives, or the error message after the retry."""
    error = None
    for _ in range(ATTEMPTS):
        try:
            result = simulate(plan, scenario, dict(task.point), objectives=objectives, timeout=timeout,
                              experiment=experiment)
            return result.objectives, None
        except DseError as e:
            error = str(e)
        except Exception as e:  # a bug or an FMU misbehaving in a way we did not foresee
            error = f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=3)}"
    return None, error


def run_chunk(job: ChunkJob) -> ChunkSummary:
    """Simulate a chunk on a worker and write its rows; return only counts."""
    unpacked = ship.received(job.shipment)
    worker, rows, errors = _worker_name(), [], []
    started = time.perf_counter()
    for task in job.tasks:
        scenario = unpacked.scenarios[task.scenario]
        t0 = time.perf_counter()
        scores, error = run_task(unpacked.plan, task, scenario, job.objectives, job.timeout, job.experiment)
        if error and len(errors) < 3:
            errors.append(f"{task.scenario} {dict(task.point)}: {error}")
        rows.append(_row(job, task, scenario.group, scores, error, time.perf_counter() - t0, worker))
    seconds = time.perf_counter() - started
    store.write_rows(job.output, job.sweep, job.chunk_id, rows, job.schema)
    failed = sum(r["status"] == "failed" for r in rows)
    return ChunkSummary(job.chunk_id, len(rows) - failed, failed, seconds, errors)


def _row(job: ChunkJob, task: Task, group: str, scores: dict[str, Any] | None, error: str | None,
         wall_time: float, worker: str) -> dict[str, Any]:
    return {
        "task_id": task.task_id, "model": job.model_key, "scenario": task.scenario, "group": group,
        **dict(task.point),
        **(scores or {name: None for name in job.objectives}),
        "status": "ok" if error is None else "failed", "error": error,
        "wall_time": wall_time, "worker": worker,
    }


def record_crash(job: ChunkJob, groups: dict[str, str], reason: str) -> ChunkSummary:
    """The failed row of a task that kept killing its worker; written by the client."""
    (task,) = job.tasks
    error = (f"the worker process died each time it ran this task ({reason}): the FMU crashed "
             "(e.g. a segmentation fault) or the process ran out of memory")
    rows = [_row(job, task, groups[task.scenario], None, error, 0.0, "")]
    store.write_rows(job.output, job.sweep, job.chunk_id, rows, job.schema)
    return ChunkSummary(job.chunk_id, 0, 1, 0.0, [f"{task.scenario} {dict(task.point)}: {error}"])


class WorkerActivity(BaseModel):
    """One Dask worker as the dashboard shows it."""

    name: str
    threads: int
    executing: int = 0  # tasks running on it now
    cpu: float = 0.0  # percent
    memory: int = 0  # bytes


class SweepReport(BaseModel):
    """What a submission has done so far: returned by :func:`submit`, shown by the progress bar,
    and saved beside the results as ``<sweep>.status.json`` for the dashboard (also when it runs
    in another process than the sweep)."""

    sweep: str
    output: str | Path
    total: int  # tasks in the space
    skipped: int  # already had a row
    spec: str = ""  # the space.yaml the sweep ran from, to find its recordings again
    scenarios: dict[str, str] = {}  # scenario -> group
    state: Literal["running", "finished", "interrupted", "failed"] = "running"  # failed: submit raised
    started_at: float = Field(default_factory=time.time)  # Unix time
    updated_at: float = Field(default_factory=time.time)
    ok: int = 0
    failed: int = 0
    seconds: float = 0.0  # wall time of this submission
    simulation_seconds: float = 0.0  # summed on the workers
    chunk_size: int = 0
    chunks: int = 0
    workers: int = 0
    activity: list[WorkerActivity] = []
    dashboard: str | None = None  # Dask's
    interrupted: bool = False
    crashed_chunks: int = 0  # chunks Dask gave up on because workers died running them; split and rerun
    reconnects: int = 0  # times the scheduler went away and the sweep resumed from the store
    waiting: str | None = None  # what the sweep is waiting for, if it is not running tasks
    errors: list[str] = []

    @property
    def ran(self) -> int:
        return self.ok + self.failed

    @property
    def remaining(self) -> int:
        return max(0, self.total - self.skipped - self.ran)

    @property
    def rate(self) -> float:
        """Simulations per second in this submission."""
        return self.ran / self.seconds if self.seconds > 0 else 0.0

    @property
    def eta_seconds(self) -> float | None:
        return self.remaining / self.rate if self.rate > 0 else None

    @property
    def seconds_per_task(self) -> float | None:
        """The mean wall time of this submission's simulations on the workers, if all went well."""
        return self.simulation_seconds / self.ok if self.ok and not self.failed else None


STATUS_FILE = "status.json"
STATUS_SECONDS = 1.0  # how often a running sweep saves its status


def save_status(report: SweepReport) -> None:
    report.updated_at = time.time()
    store.write_text(report.output, f"{report.sweep}.{STATUS_FILE}", report.model_dump_json(indent=1))


def load_status(output: store.Root, sweep: str) -> SweepReport | None:
    """The last status a submission saved, or None if no submission of ``sweep`` saved one."""
    text = store.read_text(output, f"{sweep}.{STATUS_FILE}")
    return SweepReport.model_validate_json(text) if text is not None else None


def worker_activity(client) -> list[WorkerActivity]:
    workers = client.scheduler_info()["workers"].values()
    return [WorkerActivity(name=str(w.get("name", w.get("id", "?"))), threads=w["nthreads"],
                           executing=w["metrics"].get("task_counts", {}).get("executing", 0),
                           cpu=w["metrics"].get("cpu", 0.0), memory=w["metrics"].get("memory", 0))
            for w in workers]


Progress = Callable[[SweepReport], None]


def first_point(space: Space, points: list[Point] | None = None) -> Point:
    point = next(iter(points_of(space, points)(space)), None)
    if point is None:
        raise DseError(f"{space.path}: the constraints exclude every parameter point")
    return point


def probe(shipment: str, scenario: str, point: Point, objectives: dict[str, ObjectiveSpec], timeout: float,
          experiment: Experiment | None = None) -> float | None:
    """Seconds one simulation takes on a worker, to size chunks; None if it failed (that point will
    fail in its chunk too and become a failed row, which must not stop the sweep). It runs on a worker,
    not in the client, so that an FMU that crashes its process takes down a worker, not the user's shell."""
    unpacked = ship.received(shipment)
    start = time.perf_counter()
    try:
        simulate(unpacked.plan, unpacked.scenarios[scenario], point, objectives=objectives, timeout=timeout,
                 experiment=experiment)
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
           points: list[Point] | None = None, on_connect: Callable[[Any], None] | None = None,
           only: list[Collection[str]] | None = None, seconds_per_task: float | None = None) -> SweepReport:
    """Run every task of ``space`` that has no row yet; returns counts, never raises on failed tasks.

    ``points`` replaces the space's search strategy with a given list: how an
    optimiser (fit.py) runs each of its rounds as a sweep into the same store;
    ``only`` then names, per point, the scenarios it is wanted on (expand.expand), and
    ``seconds_per_task`` what a task cost in the last round (its report's ``seconds_per_task``),
    which sizes chunks without a probe: a serial simulation every round would add up.
    ``on_connect(client)`` runs each time the sweep (re)connects to a scheduler: how the
    CLI links its dashboard from Dask's (dashboard.link_from_dask)."""
    started = time.perf_counter()
    output = space.output
    store.check_reachable(output)
    save_sweep_spec(output, space.spec, space.model_key)
    done = store.finished_task_ids(output, space.name)
    total = skipped = 0
    for task in expand(space, points, only):
        total += 1
        skipped += task.task_id in done
    report = SweepReport(sweep=space.name, output=output, total=total, skipped=skipped, spec=str(space.path),
                         scenarios={s.name: s.group for s in space.scenarios})
    pending = total - skipped
    if pending == 0 and _trajectories_kept(space):
        report.seconds = time.perf_counter() - started
        report.state = "finished"
        save_status(report)
        return report
    point = first_point(space, points)
    run = Run(space, ship.pack(space.plan, space.scenarios), points, report, progress, started, on_connect,
              only=only, seconds_per_task=seconds_per_task)
    save_status(report)
    try:
        if client is None:
            with connect(space.spec.cluster, space.path.parent) as own:
                return run.until_done(own, done, point, pending)
        return run.until_done(client, done, point, pending)
    except DseError:
        report.state = "failed"  # so a dashboard does not wait for a sweep that has stopped
        save_status(report)
        raise


def _trajectories_kept(space: Space) -> bool:
    wanted = space.spec.keep_trajectories
    return not wanted or all(store.has_trajectory(space.output, space.name, s.name, wanted) for s in space.scenarios)


class SchedulerLost(Exception):
    """The client's connection to the scheduler broke mid-sweep."""


@dataclass
class Run:
    """One submission: keeps chunks in flight, handles crashed chunks, and resumes after a scheduler restart."""

    space: Space
    shipment: ship.Shipment
    points: list[Point] | None
    report: SweepReport
    progress: Progress | None
    started: float
    on_connect: Callable[[Any], None] | None = None
    saved: float = 0.0  # when the status file was last written (monotonic)
    only: list[Collection[str]] | None = None  # per given point, the scenarios it runs on
    seconds_per_task: float | None = None  # known from an earlier round; else probed

    def until_done(self, client, done: set[str], point: Point, pending: int) -> SweepReport:
        report = self.report
        if pending:
            ship.send(client, self.shipment)
            self._connected(client)
            cost = self.seconds_per_task or self._probe(client, point)
            report.chunk_size = chunk_size(cost, self.space.spec.chunk_seconds,
                                           pending, total_threads(client))
            while True:
                try:
                    self._chunks(client, done)
                    break
                except SchedulerLost:
                    self._reconnect(client)  # a new scheduler knows neither our plugin nor our chunks
                    ship.send(client, self.shipment)
                    self._connected(client)
                    done = store.finished_task_ids(self.space.output, self.space.name)
        if not report.interrupted and self.space.spec.keep_trajectories:
            keep_trajectories(self.space, client, self.space.spec.keep_trajectories, self.shipment)
        report.seconds = time.perf_counter() - self.started
        report.state = "interrupted" if report.interrupted else "finished"
        save_status(report)
        return report

    def _connected(self, client) -> None:
        self.report.workers = len(client.scheduler_info()["workers"])
        self.report.dashboard = client.dashboard_link
        if self.on_connect:
            self.on_connect(client)

    def _chunks(self, client, done: set[str]) -> None:
        from distributed import as_completed
        from distributed.comm.core import CommClosedError
        from distributed.scheduler import KilledWorker

        report, threads = self.report, total_threads(client)
        jobs = _jobs(self.space, self.shipment.key, done, report.chunk_size, self.points, self.only)
        again: deque[ChunkJob] = deque()  # halves of crashed chunks go first
        launched: dict[str, ChunkJob] = {}
        in_flight = as_completed()

        def launch(n: int) -> None:
            for _ in range(n):
                job = again.popleft() if again else next(jobs, None)
                if job is None:
                    return
                launched[job.key] = job
                in_flight.add(client.submit(run_chunk, job, key=job.key, pure=False))

        try:
            launch(2 * threads + 2)
            self._tell(client)
            for future in in_flight:
                job = launched.pop(future.key)
                try:
                    self._count(future.result())
                except KilledWorker as e:
                    report.crashed_chunks += 1
                    retry = job.after_crash()
                    again.extend(retry)
                    if not retry:  # a lone task, out of attempts
                        self._count(record_crash(job, {s.name: s.group for s in self.space.scenarios}, str(e)))
                except CommClosedError:  # the scheduler went while we fetched this chunk's result
                    raise SchedulerLost from None
                except CancelledError:
                    if client.status != "running":  # the connection to the scheduler broke
                        raise SchedulerLost from None
                    raise DseError(f"chunk {job.chunk_id} was cancelled on the scheduler {client.scheduler.address}"
                                   " by someone else; submit again to finish the sweep") from None
                launch(max(1, len(again)))  # a split chunk's halves take its place and one more
                self._tell(client)
        except KeyboardInterrupt:
            report.interrupted = True
            for future in list(in_flight.futures):
                future.cancel()

    def _probe(self, client, point: Point) -> float | None:
        from distributed.scheduler import KilledWorker

        spec = self.space.spec
        future = client.submit(probe, self.shipment.key, self.space.scenarios[0].name, point, self.space.objectives,
                               spec.timeout, self.space.experiment, pure=False)
        try:
            return future.result()
        except KilledWorker:
            return None

    def _count(self, summary: ChunkSummary) -> None:
        report = self.report
        report.ok += summary.ok
        report.failed += summary.failed
        report.chunks += 1
        report.simulation_seconds += summary.seconds
        report.errors.extend(summary.errors[: max(0, 5 - len(report.errors))])

    def _tell(self, client) -> None:
        """Show progress; save the status for the dashboard at most every STATUS_SECONDS."""
        report = self.report
        report.seconds = time.perf_counter() - self.started
        if self.progress:
            self.progress(report)
        if time.monotonic() - self.saved >= STATUS_SECONDS:
            try:
                if client.status == "running":
                    report.activity = worker_activity(client)
                    report.workers = len(report.activity)
            except OSError:  # the scheduler went just now: keep the last activity; the sweep deals with it
                pass
            save_status(report)
            self.saved = time.monotonic()

    def _reconnect(self, client) -> None:
        """Wait for the client to reconnect to a restarted scheduler and for a worker to join it.

        distributed's client retries the scheduler's address for ``connect_timeout`` seconds; workers
        exit when their scheduler goes, so their supervisor (HTCondor, Kubernetes, systemd) must start
        new ones, for which we wait as long again."""
        timeout = self.space.spec.cluster.connect_timeout
        address = client.scheduler.address
        self.report.waiting = f"scheduler {address} lost; waiting for it"
        self._tell(client)
        deadline = time.monotonic() + timeout
        while client.status == "connecting" and time.monotonic() < deadline:
            time.sleep(0.2)
        try:
            if client.status != "running":
                raise TimeoutError
            client.wait_for_workers(1, timeout=timeout)
        except (TimeoutError, OSError):
            raise DseError(f"lost the Dask scheduler at {address} and it did not come back with a worker within "
                           f"{timeout:g} s (cluster.connect_timeout); every finished chunk is in "
                           f"{self.report.output}: submit again to run the rest") from None
        self.report.reconnects += 1
        self.report.waiting = None


def _trajectory(shipment: str, model_key: str, scenario: str, point: dict[str, Any], output: store.Root,
                sweep: str, place: int, experiment: Experiment | None = None) -> str:
    unpacked = ship.received(shipment)
    result = simulate(unpacked.plan, unpacked.scenarios[scenario], point, objectives={}, experiment=experiment)
    frame = pd.DataFrame(result.trajectory.values, columns=list(result.trajectory.names))
    frame.insert(0, "time", result.trajectory.time)
    for name, value in point.items():
        frame[f"point:{name}"] = value
    return store.write_trajectory(output, sweep, scenario, place, frame)


def keep_trajectories(space: Space, client, count: int, shipment: ship.Shipment) -> list[str]:
    """Simulate the ``count`` best points again on every scenario and keep their tracks."""
    try:
        ranking = rank(space.output, space.name)
    except DseError:
        return []  # nothing complete to rank: no best points
    best = ranking.totals.head(count)[ranking.parameters].to_dict("records")
    return _trajectories(space, client, shipment, [(place, point) for place, point in enumerate(best, start=1)],
                         space.name)


def _trajectories(space: Space, client, shipment: ship.Shipment, places: list[tuple[int, dict[str, Any]]],
                  sweep: str) -> list[str]:
    ship.send(client, shipment)
    key = space.model_key
    futures = [client.submit(_trajectory, shipment.key, key, scenario.name, point, space.output, sweep, place,
                             space.experiment, pure=False)
               for place, point in places for scenario in space.scenarios]
    return client.gather(futures)


def trajectories_of(space: Space, client, point: dict[str, Any], sweep: str) -> dict[str, pd.DataFrame]:
    """Simulate one point on every scenario on the cluster, keep the tracks as ``sweep``'s rank 1,
    and return them by scenario."""
    _trajectories(space, client, ship.pack(space.plan, space.scenarios), [(1, point)], sweep)
    return {s.name: store.read_trajectory(space.output, sweep, s.name) for s in space.scenarios}


def _jobs(space: Space, shipment: str, done: set[str], size: int, points: list[Point] | None,
          only: list[Collection[str]] | None = None) -> Iterator[ChunkJob]:
    key = space.model_key
    schema = store.results_schema(space.parameters, space.objectives)
    todo = (t for t in expand(space, points, only) if t.task_id not in done)
    for tasks in chunked(todo, size):
        yield ChunkJob(space.name, _chunk_id(tasks), shipment, key, TaskBatch.of(tasks), space.objectives,
                       space.output, schema, space.spec.timeout, space.experiment)
