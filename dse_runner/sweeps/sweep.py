"""Running a design space on Dask: chunks of tasks in, Parquet partitions out.

The client expands the space lazily, skips tasks that already have a row,
ships the FMUs and recordings to the workers (ship.py) and keeps a bounded
number of chunks in flight; for a closed-loop search the chunks come from
its strategy instead (closed_loop.py). Each chunk runs on a worker
(chunks.run_chunk),
which simulates its tasks with the worker's cached FMU instances, writes the
rows to the store itself and returns only a small summary, so the client's
memory does not grow with the sweep.

What can go wrong, and what happens:

- a simulation fails or diverges: a failed row after one retry; the sweep goes on;
- a worker dies (killed, out of memory): Dask runs its chunk again elsewhere;
- a chunk keeps killing workers (an FMU that segfaults): it is split in halves
  until each task is alone; alone, a task runs in a process of its own, so the
  one that crashes gets a failed row, and one that only waited on the same
  worker (Dask blames them all) runs;
- the scheduler restarts: the client reconnects, re-reads the store and runs
  what is missing;
- the client is interrupted (Ctrl-C): chunks not started are cancelled, and
  those running finish and write their rows before it stops;
- the client is killed: finished chunks are in the store (running ones finish
  on a cluster that outlives it); submitting again runs the rest.
"""

from __future__ import annotations

import math
import time
import warnings
from collections import deque
from collections.abc import Callable, Collection, Iterator
from concurrent.futures import CancelledError
from dataclasses import dataclass, field
from typing import Any, Protocol

import pandas as pd

from ..errors import DseError
from ..simulation.experiment import Experiment
from ..simulation.run import simulate
from . import ship, store
from .chunks import ChunkJob, ChunkSummary, TaskScores, chunk_id_of, probe, record_crash, run_chunk
from .closed_loop import SearchSource
from .cluster import WorkerWatch, connect, total_threads, wait_until_ended, worker_grace
from .domain import Point
from .expand import TaskBatch, blocks, chunked, count, distinct, points_of, tally, undone
from .rank import rank, save_sweep_spec
from .search import BudgetWarning, strategy
from .spec import Space

# The status file's models live in status.py; importing them from here keeps working.
from .status import STATUS_SECONDS, SearchStatus, SweepReport, WorkerActivity, load_status, save_status


def worker_activity(client) -> list[WorkerActivity]:
    workers = client.scheduler_info()["workers"].values()
    return [
        WorkerActivity(
            name=str(w.get("name", w.get("id", "?"))),
            threads=w["nthreads"],
            executing=w["metrics"].get("task_counts", {}).get("executing", 0),
            cpu=w["metrics"].get("cpu", 0.0),
            memory=w["metrics"].get("memory", 0),
        )
        for w in workers
    ]


SweepProgress = Callable[[SweepReport], None]  # told the sweep's counts each time they change (the CLI's bar)


def first_point(space: Space, points: list[Point] | None = None) -> Point:
    point = next(iter(points_of(space, points)(space)), None)
    if point is None:
        raise DseError(f"{space.path}: the constraints exclude every parameter point")
    return point


UNKNOWN_TASK_SECONDS = 0.1  # when the probe failed: a guess that keeps chunks small
SMALLEST_CHUNK_PART = 20  # the smallest chunk holds this part of chunk_seconds of work


def chunk_size(
    seconds_per_task: float | None,
    target_seconds: float,
    pending: int,
    threads: int,
    round_: int | None = None,
) -> int:
    """Tasks per chunk: long enough that Dask's per-task cost (~ms) is under 1-5% of the
    chunk, short enough that every thread gets several chunks to balance the load. Chunks of
    the ``round_`` (0, 1, ...) since the sweep (re)started ramp up from the smallest size,
    doubling each round: with cheap tasks, making a chunk takes the client a while, and so
    each round is made while the workers run the last, and the first starts at once."""
    per_task = UNKNOWN_TASK_SECONDS if seconds_per_task is None else max(seconds_per_task, 1e-6)
    by_time = max(1, round(target_seconds / per_task))
    at_least = max(1, round(target_seconds / SMALLEST_CHUNK_PART / per_task))  # the last chunks still pay
    by_balance = max(1, math.ceil(pending / (4 * threads)), at_least)
    ramp = at_least * 2 ** min(round_, 30) if round_ is not None else by_balance
    return min(by_time, by_balance, ramp)


def submit(
    space: Space,
    progress: SweepProgress | None = None,
    client=None,
    points: list[Point] | None = None,
    on_connect: Callable[[Any], None] | None = None,
    only: list[Collection[str]] | None = None,
    seconds_per_task: float | None = None,
    told: list[TaskScores] | None = None,
    tasks: list[TaskBatch] | None = None,
) -> SweepReport:
    """Run ``space``: every task of a grid strategy that has no row yet, or a closed-loop search
    (closed_loop.py) until its budget; returns counts, never raises on failed tasks.

    ``points`` replaces the space's search strategy with a given list: how an
    optimiser (fit.py) runs each of its rounds as a sweep into the same store;
    ``only`` then names, per point, the scenarios it is wanted on (expand.expand), and
    ``seconds_per_task`` what a task cost in the last round (its report's ``seconds_per_task``),
    which sizes chunks without a probe: a serial simulation every round would add up;
    ``told``, a list, receives the objectives of every task simulated, as its chunk finishes,
    so that an optimiser need not read back from the store the rows it has just caused;
    ``tasks``, the tasks of ``points`` (and ``only``) as expand.blocks makes them, if the caller has them
    already; otherwise they are made here, once for both the count and the chunks.
    ``on_connect(client)`` runs each time the sweep (re)connects to a scheduler: how the
    CLI links its dashboard from Dask's (dask_link.link_from_dask)."""
    started = time.perf_counter()
    output = space.output
    store.check_reachable(output)
    save_sweep_spec(output, space.spec, space.model_key, space.draws)
    done = store.finished_task_ids(output, space.name)
    kept = load_status(output, space.name)  # a submission that finds nothing to run leaves it as it is
    shipment = ship.pack(space.plan, space.scenarios, space.modules)
    report = SweepReport(
        sweep=space.name,
        output=output,
        total=0,
        skipped=0,
        spec=str(space.path),
        scenarios={s.name: s.group for s in space.scenarios},
    )
    if points is None and strategy(space.spec.search.strategy).closed_loop:
        search = space.spec.search
        report.search = SearchStatus(
            strategy=search.strategy,
            objective=space.spec.ranking.objective,
            goal=space.spec.ranking.goal,
            max_points=search.max_points,
            max_seconds=search.max_seconds,
        )
        report.total = search.max_points * len(space.scenarios)
        source: JobSource = SearchSource(space, shipment.key, report.search)
    else:
        if points is None and (note := space.strategy().spending()):
            warnings.warn(BudgetWarning(note), stacklevel=2)
        if points is not None and tasks is None:
            points, only = distinct(points, only)  # a repeat would be a second chunk of the same tasks
            tasks = list(blocks(space, points, only))  # a given list of points: its tasks fit in memory
        report.total, report.skipped = (
            count(space, done, points, only) if tasks is None else tally(tasks, done)
        )
        if report.total == report.skipped and _trajectories_kept(space):
            report.seconds = time.perf_counter() - started
            report.state = "finished"
            save_status(report, kept)
            return report
        source = GridSource(space, shipment.key, report, points, only, seconds_per_task, told, tasks)
    run = Run(space, shipment, source, report, progress, started, on_connect, kept)
    save_status(report)
    try:
        if client is None:
            with connect(space.spec.cluster, space.path.parent) as own:
                return run.until_done(own, done)
        return run.until_done(client, done)
    except DseError:
        report.state = "failed"  # so a dashboard does not wait for a sweep that has stopped
        save_status(report)
        raise
    except KeyboardInterrupt:  # while it starts, probes or keeps tracks (the chunks' loop returns instead)
        report.state = "interrupted"
        save_status(report)
        raise


def tasks_done(space: Space) -> tuple[int, int]:
    """(tasks with a row in the store, tasks): read from the store, so that after an interruption, once
    the last chunk has written, it is what submitting again finds done. The client's own count misses
    chunks that finished after it stopped listening. A search's tasks are its budget (``max_points`` on
    every scenario), and its rows are those of the current model."""
    if strategy(space.spec.search.strategy).closed_loop:
        rows = store.read_results(space.output, space.name, ["model"])
        budget = space.spec.search.max_points * len(space.scenarios)
        return int((rows["model"] == space.model_key).sum()), budget
    total, done = count(space, store.finished_task_ids(space.output, space.name))
    return done, total


def _trajectories_kept(space: Space) -> bool:
    wanted = space.spec.keep_trajectories
    return not wanted or all(
        store.has_trajectory(space.output, space.name, s.name, wanted) for s in space.scenarios
    )


class SchedulerLost(Exception):
    """The client's connection to the scheduler broke mid-sweep."""


class JobSource(Protocol):
    """Where a run's chunks come from: a grid's chunks (GridSource) or a search's points (SearchSource)."""

    def start(self, client, done: store.TaskIds) -> None:
        """(Re)connected to the cluster of ``client``; ``done``: task ids with a row."""

    def next(self, in_flight: int) -> ChunkJob | None:
        """The next chunk to send while ``in_flight`` run; None: none for now."""

    def finished(self, job: ChunkJob, summary: ChunkSummary) -> None:
        """A chunk's result."""

    def save(self) -> None:
        """Keep what the source needs to resume (the end of a run, or an interruption)."""


@dataclass
class GridSource:
    """Chunks of the grid's tasks that have no row, of about ``chunk_seconds`` each: sized first by a probe,
    then by what finished chunks cost, and smaller towards the end."""

    space: Space
    shipment: str
    report: SweepReport
    points: list[Point] | None = None
    only: list[Collection[str]] | None = None
    seconds_per_task: float | None = None  # known from an earlier round, else probed; then measured
    told: list[TaskScores] | None = None  # receives every task's objectives (submit's ``told``)
    tasks: list[TaskBatch] | None = None  # the points' tasks, made already (submit's ``tasks``)
    jobs: Iterator[ChunkJob] | None = None
    capacity: int = 1
    threads: int = 1
    unassigned: int = 0  # tasks not yet in a chunk
    sent: int = 0  # chunks handed out since the last (re)connection
    warm_ups: list[Any] = field(default_factory=list)  # the probes' futures, kept so that none is cancelled

    def start(self, client, done: store.TaskIds) -> None:
        self.threads = total_threads(client)
        self.unassigned = self.report.remaining
        if self.seconds_per_task is None:
            self.warm_up(client, first_point(self.space, self.points))
        self.jobs = _jobs(
            self.space,
            self.shipment,
            done,
            self._size,
            self.points,
            self.only,
            with_scores=self.told is not None,
            tasks=self.tasks,
        )  # while they run
        self.seconds_per_task = self.seconds_per_task or self.probed(client)
        self.capacity = 2 * self.threads + 2
        self.sent = 0

    def next(self, in_flight: int) -> ChunkJob | None:
        if self.jobs is None or in_flight >= self.capacity:
            return None
        job = next(self.jobs, None)
        if job is not None:
            self.unassigned -= len(job.tasks)
        return job

    def finished(self, job: ChunkJob, summary: ChunkSummary) -> None:
        """Chunks adapt: the next ones are sized by what this one cost on its worker (its whole time,
        rows written included), which the probe of one simulation can only estimate."""
        tasks = summary.ok + summary.failed
        if tasks and summary.busy > 0:
            self.seconds_per_task = summary.busy / tasks
        if self.told is not None:
            self.told.extend(summary.scores)

    def _size(self) -> int:
        """The next chunk's size: by the latest cost per task, and by the tasks not yet handed out, so
        chunks shrink towards the end and no worker idles long while another finishes a big one."""
        size = chunk_size(
            self.seconds_per_task,
            self.space.spec.chunk_seconds,
            self.unassigned,
            self.threads,
            self.sent // self.threads,
        )
        self.sent += 1
        self.report.chunk_size = max(self.report.chunk_size, size)
        return size

    def save(self) -> None:
        pass  # the rows are all a grid needs

    def warm_up(self, client, point: Point) -> None:
        """Probe one warm simulation on every worker at once: each loads the model while the client makes
        the results' schema, so none of them starts its first chunk cold."""
        spec = self.space.spec
        # none yet (an adaptive cluster starts from no worker): one probe anywhere, which asks for the first
        workers = [[address] for address in client.scheduler_info()["workers"]] or [None]
        self.warm_ups = [
            client.submit(
                probe,
                self.shipment,
                self.space.scenarios[0].name,
                point,
                self.space.objectives,
                spec.timeout,
                self.space.experiment,
                workers=where,
                allow_other_workers=True if where else None,
                pure=False,
            )
            for where in workers
        ]

    def probed(self, client) -> float | None:
        """The first probe's answer (the others go on, as warm-ups); None if it failed. Watched like the
        chunks: a cluster that loses every worker while it probes stops the sweep, not waits for ever."""
        from distributed import as_completed
        from distributed.scheduler import KilledWorker

        with WorkerWatch(client, worker_grace(self.space.spec.cluster), lambda: self.warm_ups) as watch:
            for future in as_completed(self.warm_ups):
                try:
                    return future.result()
                except KilledWorker:  # the model crashes its process: no more workers should die probing it
                    client.cancel(self.warm_ups)
                    return None
                except CancelledError:
                    if watch.stranded:
                        raise DseError(
                            f"while the sweep timed its first simulation, {watch.stranded}; every "
                            f"finished chunk is in {self.space.output}: start workers and submit "
                            "again"
                        ) from None
                    raise
        return None


@dataclass
class Run:
    """One submission: keeps chunks in flight, handles crashed chunks, and
    resumes after a scheduler restart."""

    space: Space
    shipment: ship.Shipment
    source: JobSource
    report: SweepReport
    progress: SweepProgress | None
    started: float
    on_connect: Callable[[Any], None] | None = None
    kept: SweepReport | None = None  # the status when the submission started (save_status)
    saved: float = 0.0  # when the status file was last written (monotonic)

    def until_done(self, client, done: store.TaskIds) -> SweepReport:
        report = self.report
        if report.search is not None or report.total > report.skipped:
            ship.send(client, self.shipment)
            self._connected(client)
            self.source.start(client, done)
            try:
                while True:
                    try:
                        self._chunks(client)
                        break
                    except SchedulerLost:
                        self._reconnect(client)  # a new scheduler knows neither our plugin nor our chunks
                        ship.send(client, self.shipment)
                        self._connected(client)
                        self.source.start(client, store.finished_task_ids(self.space.output, self.space.name))
            finally:
                self.source.save()  # also when the run fails: what was told stays replayable
        if not report.interrupted and self.space.spec.keep_trajectories:
            keep_trajectories(self.space, client, self.space.spec.keep_trajectories, self.shipment)
        report.seconds = time.perf_counter() - self.started
        report.state = "interrupted" if report.interrupted else "finished"
        save_status(report, self.kept)
        return report

    def _connected(self, client) -> None:
        self.report.workers = len(client.scheduler_info()["workers"])
        self.report.dashboard = client.dashboard_link
        if self.on_connect:
            self.on_connect(client)

    def _chunks(self, client) -> None:
        from distributed import as_completed

        report, source = self.report, self.source
        again: deque[ChunkJob] = deque()  # halves of crashed chunks go first
        launched: dict[str, ChunkJob] = {}
        in_flight = as_completed()

        def fill() -> None:
            while True:
                job = again.popleft() if again else source.next(len(launched))
                if job is None:
                    return
                launched[job.key] = job
                in_flight.add(client.submit(run_chunk, job, key=job.key, pure=False))

        # A chunk as_completed has handed over is no longer in flight, but its result may still be on its
        # worker: if every worker dies before it arrives, the watch must cancel that one too
        fetching: list = []
        watch = WorkerWatch(
            client, worker_grace(self.space.spec.cluster), lambda: [*in_flight.futures, *fetching]
        )
        try:
            with watch:
                self._wait(client, in_flight, launched, again, fill, watch, fetching)
        except KeyboardInterrupt:
            report.interrupted = True
            if report.search is not None:
                report.search.stopped = "interrupted"
            running = list(in_flight.futures)
            client.cancel(running)  # those not started never will
            wait_until_ended(client, [future.key for future in running])  # those started write their rows

    def _wait(
        self,
        client,
        in_flight,
        launched: dict[str, ChunkJob],
        again: deque[ChunkJob],
        fill: Callable[[], None],
        watch: WorkerWatch,
        fetching: list,
    ) -> None:
        """Count each chunk as it finishes and send the next; split crashed chunks."""
        from distributed.comm.core import CommClosedError
        from distributed.scheduler import KilledWorker

        report = self.report
        fill()
        self._tell(client)
        for future in in_flight:
            job = launched.pop(future.key)
            fetching[:] = [future]
            try:
                self._count(job, future.result())
            except KilledWorker as e:
                report.crashed_chunks += 1
                store.remove_chunk(
                    job.output, job.sweep, job.chunk_id
                )  # if it finished before its worker died
                retry = job.after_crash()
                again.extend(retry)
                if not retry:  # a lone task, out of attempts
                    self._count(
                        job, record_crash(job, {s.name: s.group for s in self.space.scenarios}, str(e))
                    )
            except CommClosedError:  # the scheduler went while we fetched this chunk's result
                raise SchedulerLost from None
            except CancelledError:
                if watch.stranded:
                    raise DseError(
                        f"{watch.stranded}; every finished chunk is in {report.output}: start "
                        "workers (or mend what killed them) and submit again to run the rest"
                    ) from None
                if client.status != "running":  # the connection to the scheduler broke
                    raise SchedulerLost from None
                raise DseError(
                    f"chunk {job.chunk_id} was cancelled on the scheduler {client.scheduler.address}"
                    " by someone else; submit again to finish the sweep"
                ) from None
            fill()  # a split chunk's halves go first
            self._tell(client)

    def _count(self, job: ChunkJob, summary: ChunkSummary) -> None:
        self.source.finished(job, summary)
        report = self.report
        report.ok += summary.ok
        report.failed += summary.failed
        report.chunks += 1
        report.simulation_seconds += summary.seconds
        report.chunk_seconds += summary.busy
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
        new ones, for which we wait as long again. The client may not yet have noticed the loss when we
        get here (its status still says running): a call that fails on the dead connection is retried."""
        timeout = self.space.spec.cluster.connect_timeout
        address = client.scheduler.address
        self.report.waiting = f"scheduler {address} lost; waiting for it"
        self._tell(client)
        deadline = time.monotonic() + 2 * timeout
        while client.status in ("running", "connecting") and time.monotonic() < deadline:
            if client.status == "running":
                try:
                    client.wait_for_workers(1, timeout=max(1.0, deadline - time.monotonic()))
                    break
                except OSError:  # the old connection, not yet seen closed; or no worker in time
                    pass
            time.sleep(0.2)
        else:
            raise DseError(
                f"lost the Dask scheduler at {address} and it did not come back with a worker within "
                f"{2 * timeout:g} s (twice cluster.connect_timeout); every finished chunk is in "
                f"{self.report.output}: submit again to run the rest"
            )
        self.report.reconnects += 1
        self.report.waiting = None


def _trajectory(
    shipment: str,
    model_key: str,
    scenario: str,
    point: Point,
    output: store.Root,
    sweep: str,
    place: int,
    experiment: Experiment | None = None,
) -> str:
    unpacked = ship.received(shipment)
    result = simulate(
        unpacked.plan, unpacked.scenarios[scenario], point, objectives={}, experiment=experiment
    )
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
    return _trajectories(
        space, client, shipment, [(place, point) for place, point in enumerate(best, start=1)], space.name
    )


def _trajectories(
    space: Space, client, shipment: ship.Shipment, places: list[tuple[int, Point]], sweep: str
) -> list[str]:
    ship.send(client, shipment)
    key = space.model_key
    futures = [
        client.submit(
            _trajectory,
            shipment.key,
            key,
            scenario.name,
            point,
            space.output,
            sweep,
            place,
            space.experiment,
            pure=False,
        )
        for place, point in places
        for scenario in space.scenarios
    ]
    return client.gather(futures)


def trajectories_of(space: Space, client, point: Point, sweep: str) -> dict[str, pd.DataFrame]:
    """Simulate one point on every scenario on the cluster, keep the tracks as ``sweep``'s rank 1,
    and return them by scenario."""
    _trajectories(space, client, ship.pack(space.plan, space.scenarios, space.modules), [(1, point)], sweep)
    return {s.name: store.read_trajectory(space.output, sweep, s.name) for s in space.scenarios}


def _jobs(
    space: Space,
    shipment: str,
    done: store.TaskIds,
    size: Callable[[], int],
    points: list[Point] | None,
    only: list[Collection[str]] | None = None,
    with_scores: bool = False,
    tasks: list[TaskBatch] | None = None,
) -> Iterator[ChunkJob]:
    """The chunks, made as they are asked for (of ``tasks`` when they are made already); the
    results' schema (a walk over every value of a large grid) is made now, and ``size`` is first
    asked when the first chunk is."""
    key = space.model_key
    schema = store.results_schema(space.parameters, space.objectives)
    batches = blocks(space, points, only, done) if tasks is None else undone(tasks, done)
    return (
        ChunkJob(
            space.name,
            chunk_id_of(chunk),
            shipment,
            key,
            chunk,
            space.objectives,
            space.output,
            schema,
            space.spec.timeout,
            space.experiment,
            with_scores=with_scores,
        )
        for chunk in chunked(batches, size)
    )
