"""The worker's side of a sweep: run one chunk of (point, scenario) tasks and write its rows.

A chunk is a :class:`ChunkJob`: small and picklable, naming the shipment
(ship.py) that holds the model and scenarios. :func:`run_chunk` simulates
its tasks with the worker's cached FMU instances, writes the rows to the
store itself and returns only a :class:`ChunkSummary`, so the client's memory
does not grow with the sweep. A search (closed_loop.py) also wants each
task's objective values back, to tell its strategy.

A task whose FMU asked to stop early (:class:`~dse_runner.simulation.trajectory.Stop`) has a row of status
``stopped``, its objectives over the span it reached (``span_end``); a search is told it as a failure: a
strategy compares numbers alone, and objectives over a shorter span would mislead it.
"""

from __future__ import annotations

import hashlib
import os
import socket
import time
import traceback
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pyarrow as pa

from ..errors import DseError
from ..simulation.experiment import Experiment
from ..simulation.objectives import ObjectiveSpec
from ..simulation.plan import Plan
from ..simulation.run import simulate
from ..simulation.scenario import Scenario
from ..simulation.trajectory import Stop
from . import ship, store
from .domain import Point
from .expand import TaskBatch

ATTEMPTS = 2  # a failing simulation is retried once
CRASH_ATTEMPTS = 3  # a lone task whose worker died under it this often (beyond Dask's own retries) has failed


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
    fresh_process: bool = False  # each task in a process of its own: a lone task from a crashed chunk
    with_scores: bool = False  # return every task's objectives in the summary (a search tells them)
    point: int | None = (
        None  # a search's point number (closed_loop.py); kept by the halves of a crashed chunk
    )

    @property
    def key(self) -> str:
        return f"chunk-{self.chunk_id}-{self.crashes}"

    def after_crash(self) -> list[ChunkJob]:
        """What to run after workers kept dying under this chunk: its halves, or the lone task again.

        A task alone runs in a process of its own. Dask blames a dead worker on every task it had been
        given, running or waiting, so a lone task may be innocent: alone in its process, the culprit
        fails its own row (its process killed by the signal) and an innocent one runs. One that workers
        still die under was not what killed them, or exhausts the machine's memory."""
        tasks = self.tasks
        if len(tasks) == 1:
            again = replace(self, crashes=self.crashes + 1, fresh_process=True)
            return [again] if again.crashes < CRASH_ATTEMPTS else []
        middle = len(tasks) // 2
        return [
            replace(self, chunk_id=chunk_id_of(part), tasks=part, crashes=0, fresh_process=len(part) == 1)
            for part in (tasks[:middle], tasks[middle:])
        ]


@dataclass(frozen=True)
class TaskScores:
    """One task's outcome as a search needs it."""

    task_id: str
    scenario: str
    objectives: dict[str, Any] | None  # None: the task failed
    error: str | None = None


@dataclass
class ChunkSummary:
    chunk_id: str
    ok: int
    failed: int
    seconds: float  # wall time of the simulations
    errors: list[str] = field(default_factory=list)  # first few failure messages
    scores: list[TaskScores] = field(default_factory=list)  # with_scores: one per task
    busy: float = 0.0  # wall time of the whole chunk on the worker: simulations, unpacking, writing rows


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().name)
    except (ImportError, ValueError):
        return f"{socket.gethostname()}:{os.getpid()}"


@dataclass(frozen=True)
class TaskRun:
    """One task's outcome on the worker: its objectives, or the error after the retry; how its run lived
    (reset or process); and, where an FMU asked to stop early, the stop. ``end``: the time the objectives
    are computed up to (the experiment's stop time, or the stop's), None for a failure."""

    objectives: dict[str, Any] | None
    error: str | None = None
    life: str | None = None
    stopped: Stop | None = None
    end: float | None = None

    @property
    def status(self) -> str:
        """The row's status: ok, stopped (an FMU asked to stop early; objectives over ``end``) or failed."""
        return "failed" if self.error is not None else "stopped" if self.stopped is not None else "ok"

    @property
    def note(self) -> str | None:
        """The row's ``error``: the failure, or which FMU asked to stop and when."""
        return self.error or (f"{self.stopped.instance}: {self.stopped.message}" if self.stopped else None)

    @property
    def told(self) -> dict[str, Any] | None:
        """The objectives a search is told: none for a run that stopped early, as for a failure."""
        return self.objectives if self.status == "ok" else None


def run_task(
    plan: Plan,
    point: Point,
    scenario: Scenario,
    objectives: dict[str, ObjectiveSpec],
    timeout: float,
    experiment: Experiment | None = None,
    fresh_process: bool = False,
) -> TaskRun:
    """Objectives, or the error message after the retry; how the run lived; where it stopped early, if so."""
    error = None
    for _ in range(ATTEMPTS):
        try:
            result = simulate(
                plan,
                scenario,
                point,
                objectives=objectives,
                timeout=timeout,
                experiment=experiment,
                fresh_process=fresh_process,
            )
            life = "process" if result.fresh_process else "reset"
            trajectory = result.trajectory
            return TaskRun(result.objectives, None, life, trajectory.stopped, trajectory.end)
        except DseError as e:
            error = str(e)
        except Exception as e:  # noqa: BLE001  (a bug, or an FMU misbehaving unforeseen: the row says)
            error = f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=3)}"
    return TaskRun(None, error)


def run_chunk(job: ChunkJob) -> ChunkSummary:
    """Simulate a chunk on a worker and write its rows; return only counts."""
    began = time.perf_counter()
    unpacked = ship.received(job.shipment)
    runs: list[TaskRun] = []
    walls: list[float] = []
    messages: list[str] = []
    told: list[TaskScores] = []
    started = time.perf_counter()
    for scenario, point in job.tasks.points():
        t0 = time.perf_counter()
        run = run_task(
            unpacked.plan,
            point,
            unpacked.scenarios[scenario],
            job.objectives,
            job.timeout,
            job.experiment,
            job.fresh_process,
        )
        walls.append(time.perf_counter() - t0)
        runs.append(run)
        if run.error and len(messages) < 3:
            messages.append(f"{scenario} {point}: {run.error}")
    if job.with_scores:
        told = [
            TaskScores(task.task_id, task.scenario, run.told, run.note) for task, run in zip(job.tasks, runs)
        ]
    seconds = time.perf_counter() - started
    groups = {name: scenario.group for name, scenario in unpacked.scenarios.items()}
    store.write_results(
        job.output, job.sweep, job.chunk_id, *results_table(job, groups, runs, walls, _worker_name())
    )
    failed = sum(run.error is not None for run in runs)
    return ChunkSummary(
        job.chunk_id, len(runs) - failed, failed, seconds, messages, told, busy=time.perf_counter() - began
    )


def results_table(
    job: ChunkJob, groups: dict[str, str], runs: list[TaskRun], walls: list[float], worker: str
) -> tuple[pa.Table, list[str]]:
    """The chunk's rows (one per task, in order) as a table of ``job.schema``, and each row's scenario (the
    partition). Built column by column: a dict per row cost more than a cheap FMU's simulation."""
    batch, n = job.tasks, len(job.tasks)
    scenarios = [batch.scenarios[k] for k in batch.scenario_index.tolist()]
    numeric = batch.values.dtype != object

    def parameter(k: int) -> Any:
        column = batch.values[:, k]
        return (
            np.ascontiguousarray(column)
            if numeric
            else [v.item() if hasattr(v, "item") else v for v in column]
        )

    columns = {
        "task_id": batch.ids(),
        "model": [job.model_key] * n,
        "group": [groups[name] for name in scenarios],
        **{name: parameter(k) for k, name in enumerate(batch.parameters)},
        **{
            name: [None if run.objectives is None else run.objectives.get(name) for run in runs]
            for name in job.objectives
        },
        "status": [run.status for run in runs],
        "span_end": [run.end for run in runs],
        "error": [run.note for run in runs],
        "wall_time": walls,
        "worker": [worker] * n,
        "lifecycle": [run.life for run in runs],
    }
    return pa.Table.from_pydict(
        {name: columns[name] for name in job.schema.names}, schema=job.schema
    ), scenarios


def record_crash(job: ChunkJob, groups: dict[str, str], reason: str) -> ChunkSummary:
    """The failed row of a task that kept killing its worker; written by the client."""
    (task,) = job.tasks
    error = (
        f"workers died under this task {CRASH_ATTEMPTS} times, also while it ran in a process of its own, "
        f"where an FMU's crash would have failed the run alone ({reason}): the machine ran out of memory, or "
        "something else kills the workers"
    )
    store.write_results(
        job.output, job.sweep, job.chunk_id, *results_table(job, groups, [TaskRun(None, error)], [0.0], "")
    )
    return ChunkSummary(
        job.chunk_id,
        0,
        1,
        0.0,
        [f"{task.scenario} {dict(task.point)}: {error}"],
        [TaskScores(task.task_id, task.scenario, None, error)],
    )


def chunk_id_of(tasks: TaskBatch) -> str:
    return hashlib.sha256(b"".join(tasks.task_ids.tolist())).hexdigest()[:20]


WARM_PROBE_SECONDS = 1.0  # a first simulation shorter than this is run again, warm, to be timed


def probe(
    shipment: str,
    scenario: str,
    point: Point,
    objectives: dict[str, ObjectiveSpec],
    timeout: float,
    experiment: Experiment | None = None,
) -> float | None:
    """Seconds one warm simulation takes on a worker, to size the first chunks; None if it failed (that
    point will fail in its chunk too and become a failed row, which must not stop the sweep). It runs on a
    worker, not in the client, so that an FMU that crashes its process takes down a worker, not the user's
    shell."""
    unpacked = ship.received(shipment)

    def timed() -> float:
        start = time.perf_counter()
        simulate(
            unpacked.plan,
            unpacked.scenarios[scenario],
            point,
            objectives=objectives,
            timeout=timeout,
            experiment=experiment,
        )
        return time.perf_counter() - start

    try:
        first = timed()  # pays for loading the FMUs, which the chunk's tasks will not
        return timed() if first < WARM_PROBE_SECONDS else first
    except Exception:  # noqa: BLE001  (a failing probe only leaves the chunk size to its default)
        return None
