"""Closed-loop search on Dask: ask the strategy for points as workers free up, tell it the results.

Each point is one chunk of its (point, scenario) tasks, run by the same
worker code as a grid sweep (chunks.py) into the same store. When a chunk
comes back the point's objectives are reduced over its scenarios the way the
ranking says (``ranking.over_scenarios``; the paper's Equation 2 sums them)
and told to the strategy, which is asked for the next point at once: there
is no generation barrier unless the strategy itself holds points back.
``search.batch`` points are in flight at a time, by default one more than the
cluster has worker threads, so no worker waits while the client thinks.

Nothing is simulated twice: a point whose tasks all have rows is told from
the store. A later submission replays the search from its history
(history.py) and goes on; points the constraints reject are told as
infeasible and never simulated.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from pydantic import BaseModel, computed_field

from ..simulation.objectives import is_vector
from . import store
from .chunks import ChunkJob, ChunkSummary, TaskScores, chunk_id_of
from .cluster import total_threads
from .constraints import compile_constraint
from .domain import Point
from .expand import Task, TaskBatch, scenario_hash, task_id
from .history import SearchHistory, State, load_history, save_history, settings_digest
from .search import Evaluation, Strategy
from .spec import Space

HISTORY_SECONDS = 1.0  # how often a running search saves its history
MAX_REJECTED = 1000  # infeasible points in a row after which a search gives up asking


class SearchStatus(BaseModel):
    """How a search is going: part of the sweep's status (``<sweep>.status.json``) and of ``submit --json``."""

    strategy: str
    objective: str
    goal: str
    max_points: int
    max_seconds: float | None = None
    points: int = 0  # simulated points told to the strategy, in all submissions
    reused: int = 0  # of which told from the store without simulating (a replay), in this submission
    repeats: int = 0  # points asked again after (or while) an equal one ran: told its result, not counted
    infeasible: int = 0  # points the constraints rejected: never simulated
    failed: int = 0  # points with a failed task
    best: float | None = None  # the best reduced objective so far
    best_point: dict[str, Any] | None = None
    threads: int = 0
    busy_seconds: float = 0.0  # time the workers spent on this submission's chunks (simulating, writing rows)
    window_seconds: float = 0.0  # from the first point sent to the last result
    replayed: bool = False  # the strategy's state was rebuilt from the history
    stopped: str | None = None  # why the search ended: budget, time, strategy, interrupted
    notes: list[str] = []

    @computed_field
    @property
    def utilisation(self) -> float | None:
        """Share of the worker threads' time spent on the search's chunks while it ran."""
        if self.window_seconds <= 0 or not self.threads:
            return None
        return min(1.0, self.busy_seconds / (self.window_seconds * self.threads))


def reduce_over_scenarios(values: Iterable[float], how: str) -> float:
    array = np.asarray(list(values), dtype=float)
    return float({"sum": np.sum, "mean": np.mean, "max": np.max, "min": np.min}[how](array))


Check = tuple[str, Callable[[Mapping[str, float]], bool]]  # a ranking constraint's text and its test


def evaluation_of(scores: list[TaskScores], scalar: list[str], how: str, checks: Sequence[Check] = ()) -> Evaluation:
    """A point's evaluation from its tasks: failed if any task failed, else each objective reduced, and
    the ranking constraints (``checks``) those values break, which constrained strategies learn from."""
    failed = [s for s in scores if s.objectives is None]
    if failed:
        return Evaluation("failed", error=f"{failed[0].scenario}: {failed[0].error}")
    per = {s.scenario: s.objectives for s in scores}
    values = {name: reduce_over_scenarios((o[name] for o in per.values()), how) for name in scalar}
    return Evaluation("ok", values=values, scores=per, breaks=tuple(text for text, holds in checks if not holds(values)))


class SearchSource:
    """The chunks of a search, one per asked point, for sweep.Run to keep in flight."""

    def __init__(self, space: Space, shipment: str, status: SearchStatus):
        self.space = space
        self.shipment = shipment
        self.status = status
        self.scalar = [n for n, o in space.objectives.items() if not is_vector(o)]
        self.checks: list[Check] = [(text, compile_constraint(text, set(self.scalar), "objective"))
                                    for text in space.spec.ranking.constraints]
        self.schema = store.results_schema(space.parameters, space.objectives)
        self.hashes = {s.name: scenario_hash(s) for s in space.scenarios}
        self.strategy: Strategy | None = None
        self.history: SearchHistory | None = None
        self.stored: dict[str, TaskScores] = {}
        self.requeue: deque[int] = deque()  # points to (re)submit before asking for new ones
        self.running: dict[int, dict[str, TaskScores]] = {}  # point number -> its task results so far
        self.followers: dict[int, list[int]] = {}  # a running point -> later asks of the same point, told with it
        self.started = self.first_sent = 0.0
        self.saved = 0.0
        self.batch = 1
        self.told: set[tuple] = set()  # points told a simulation result: asking one again is a repeat
        self.rejected_in_a_row = 0
        self.stopping = False
        self.replaying = False  # the history is not saved while it is replayed

    # ---- starting and replaying ----------------------------------------------------------------

    def start(self, client, done: set[str]) -> None:
        """Called when the run (re)connects: the first time build and replay the strategy; after a
        scheduler restart send the points that were in flight again (or tell them from the store).
        ``done`` is not needed: a search reads the stored results themselves, not only their ids."""
        threads = total_threads(client)
        self.stored = self._stored_scores()
        self.status.threads = threads
        if self.strategy is not None:
            self.requeue.extend(n for n in self.running if n not in self.requeue)
            self.running.clear()
            return
        self.started = time.monotonic()
        self.strategy = self.space.strategy(threads)
        self.batch = self.strategy.problem.batch
        settings = self._settings()
        old = load_history(self.space.output, self.space.name)
        self.history = SearchHistory(sweep=self.space.name, strategy=self.space.spec.search.strategy,
                                     settings=settings)
        if old is not None and old.settings != settings:
            self.status.notes.append("the search settings changed since the last submission: a new search; "
                                     "points already simulated are reused when asked again")
        elif old is not None and old.points:
            self._replay(old, threads)

    def _settings(self) -> str:
        spec = self.space.spec
        return settings_digest(spec.search.strategy, spec.search.seed, spec.search.options,
                               [d.__dict__ for d in self.space.dimensions], spec.constraints,
                               spec.ranking.model_dump(), self.space.model_key, sorted(self.hashes.values()))

    def _replay(self, old: SearchHistory, threads: int) -> None:
        """Ask and tell a fresh strategy in the recorded order, with stored results; on any mismatch
        start afresh (the strategy is not deterministic, or rows have gone)."""
        self.replaying = True
        try:
            self._replay_events(old, threads)
        finally:
            self.replaying = False

    def _replay_events(self, old: SearchHistory, threads: int) -> None:
        for kind, asked in old.events():
            if kind == "ask":
                point = self.strategy.ask()
                if point != asked.point or self.history.ask(point) != asked.number:
                    return self._afresh(threads, f"replaying the history, the strategy asked {point} where it "
                                                 f"had asked {asked.point}")
                continue
            evaluation = self._from_store(asked.point) if asked.state != "infeasible" else Evaluation("infeasible")
            if evaluation is None:
                return self._afresh(threads, f"the results of {asked.point} are no longer in the store")
            self._tell(asked.number, evaluation, reused=True)
        self.requeue.extend(self.history.outstanding())
        self.status.replayed = True

    def _afresh(self, threads: int, why: str) -> None:
        self.status.notes.append(f"could not replay the search ({why}): a new search; points already "
                                 "simulated are reused when asked again")
        self.strategy = self.space.strategy(threads)
        self.history = SearchHistory(sweep=self.space.name, strategy=self.history.strategy,
                                     settings=self.history.settings)
        self.status.points = self.status.failed = self.status.infeasible = self.status.repeats = 0
        self.status.best = self.status.best_point = None
        self.told.clear()

    def _stored_scores(self) -> dict[str, TaskScores]:
        """Every stored task result of the current model, by task id."""
        columns = ["model", "status", "error", *self.space.objectives]
        rows = store.read_results(self.space.output, self.space.name, columns)
        rows = rows[rows["model"] == self.space.model_key]
        names = list(self.space.objectives)
        return {r["task_id"]: TaskScores(r["task_id"], r["scenario"],
                                         {n: _plain(r[n]) for n in names} if r["status"] == "ok" else None,
                                         r["error"])
                for r in rows.to_dict("records")}

    # ---- the run's side: next chunk, finished chunk -----------------------------------------------

    def next(self, in_flight: int) -> ChunkJob | None:
        while in_flight < self.batch:
            if self.requeue:
                job = self._job(self.requeue.popleft())
            else:
                if self._should_stop():
                    return None
                point = self.strategy.ask()
                if point is None:
                    self.status.stopped = self.status.stopped or ("strategy" if not self.running else None)
                    return None
                number = self.history.ask(point)
                if not self.space.admits(point):
                    self._tell(number, Evaluation("infeasible"), reused=False)
                    self.rejected_in_a_row += 1
                    if self.rejected_in_a_row >= MAX_REJECTED:
                        self.status.stopped = "infeasible"
                        self.status.notes.append(f"the strategy proposed {MAX_REJECTED} points in a row that the "
                                                 "constraints reject; loosen them or narrow the parameters' ranges")
                        self.stopping = True
                        return None
                    continue
                self.rejected_in_a_row = 0
                job = self._job(number)
            if job is not None:
                return job
        return None

    def _should_stop(self) -> bool:
        status, search = self.status, self.space.spec.search
        if self.stopping:
            return True
        if status.points + len(self.running) >= search.max_points:
            status.stopped = "budget"
            return True
        if status.repeats >= search.max_points:  # a converged strategy that only proposes what it has had
            status.stopped = "repeats"
            return True
        if search.max_seconds is not None and time.monotonic() - self.started >= search.max_seconds:
            status.stopped = "time"
            return True
        return False

    def tasks(self, point: Point) -> list[Task]:
        ordered = tuple(sorted(point.items()))
        return [Task(task_id(self.space.model_key, point, self.hashes[s.name]), s.name, ordered)
                for s in self.space.scenarios]

    def _job(self, number: int) -> ChunkJob | None:
        """The chunk of a point's tasks that have no row yet; None (and told now) if all have one."""
        point = self.history.points[number].point
        tasks = self.tasks(point)
        known = {t.task_id: self.stored[t.task_id] for t in tasks if t.task_id in self.stored}
        missing = [t for t in tasks if t.task_id not in known]
        if not missing:
            self._tell(number, evaluation_of(list(known.values()), self.scalar, self._how()), reused=True)
            return None
        leader = next((n for n in self.running if self.history.points[n].point == point), None)
        if leader is not None:  # asked again while it runs (a discrete space): told when it finishes
            self.followers.setdefault(leader, []).append(number)
            return None
        self.running[number] = known
        if not self.first_sent:
            self.first_sent = time.monotonic()
        space, batch = self.space, TaskBatch.of(missing)
        return ChunkJob(space.name, chunk_id_of(batch), self.shipment, space.model_key, batch,
                        space.objectives, space.output, self.schema, space.spec.timeout, space.experiment,
                        with_scores=True, point=number)

    def finished(self, job: ChunkJob, summary: ChunkSummary) -> None:
        self.status.busy_seconds += summary.busy
        self.status.window_seconds = time.monotonic() - self.first_sent
        results = self.running.get(job.point)
        if results is None:
            return  # told already (a chunk that finished twice, around a scheduler restart)
        for scores in summary.scores:
            results[scores.task_id] = scores
            self.stored[scores.task_id] = scores
        if len(results) == len(self.space.scenarios):
            del self.running[job.point]
            self._tell(job.point, evaluation_of(list(results.values()), self.scalar, self._how(), self.checks),
                       reused=False)

    def _how(self) -> str:
        return self.space.spec.ranking.over_scenarios

    def _from_store(self, point: Point) -> Evaluation | None:
        tasks = self.tasks(point)
        if not all(t.task_id in self.stored for t in tasks):
            return None
        return evaluation_of([self.stored[t.task_id] for t in tasks], self.scalar, self._how(), self.checks)

    def _tell(self, number: int, evaluation: Evaluation, reused: bool) -> None:
        point = self.history.points[number].point
        key = tuple(sorted(point.items()))
        self.strategy.tell(point, evaluation)
        state: State = evaluation.state
        self.history.tell(number, state, dict(evaluation.values))
        status = self.status
        if state == "infeasible":
            status.infeasible += 1
        elif key in self.told:
            status.repeats += 1
        else:
            self.told.add(key)
            status.points += 1
            status.reused += reused
            status.failed += state == "failed"
        if evaluation.feasible:  # the best the ranking may choose
            value = evaluation.values[status.objective]
            better = status.best is None or (value < status.best if status.goal == "min" else value > status.best)
            if better:
                status.best, status.best_point = value, dict(point)
        for follower in self.followers.pop(number, []):
            self._tell(follower, evaluation, reused=True)
        self.save(force=False)

    def save(self, force: bool = True) -> None:
        """The history, at most every HISTORY_SECONDS unless forced (at the end)."""
        recent = time.monotonic() - self.saved < HISTORY_SECONDS
        if self.history is None or self.replaying or (not force and recent):
            return
        save_history(self.space.output, self.history)
        self.saved = time.monotonic()


def _plain(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    return value.item() if hasattr(value, "item") else value
