"""Closed-loop search on Dask: ask the strategy for points ahead of their results, tell it the results.

Each point is one chunk of its (point, scenario) tasks, run by the same
worker code as a grid sweep (chunks.py) into the same store. When a chunk
comes back the point's objectives are reduced over its scenarios the way the
ranking says (``ranking.over_scenarios``; the paper's Equation 2 sums them)
and told to the strategy, which is then asked for the next point: there is
no generation barrier unless the strategy itself holds points back.

In which order results are told is ``search.order``:

- ``reproducible`` (the default): results are told in the order the points
  were asked, and a point is asked only while fewer than ``search.batch``
  points (4 by default, whatever the cluster) wait for theirs. So each ask
  follows the same tells, with the same points still running, whichever
  worker finishes first and however many there are: a seeded strategy asks
  the same points (Optuna's samplers and pymoo's algorithms are
  deterministic for a given seed and ask/tell sequence). A result that
  comes early waits for the points asked before it.
- ``asynchronous``: each result is told as it comes and a point asked at
  once, ``search.batch`` in flight (by default one more than the cluster's
  worker threads); no worker waits for a slow point, but the points depend
  on which finishes first.

Nothing is simulated twice: a point whose tasks all have rows is told from
the store. A later submission of a reproducible search runs it again from
the start, telling every point it asks that has rows from the store (the
same points, so no simulation until it gets past them); an asynchronous one
replays the recorded ask/tell order (history.py). Points the constraints
reject are told as infeasible at once and never simulated.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from ..simulation.objectives import is_vector
from . import store, uncertainty
from .chunks import ChunkJob, ChunkSummary, TaskScores, chunk_id_of
from .cluster import total_threads
from .constraints import compile_constraint
from .domain import Point
from .expand import Task, TaskBatch, scenario_hash, task_id
from .history import SearchHistory, State, load_history, save_history, settings_digest
from .search import Evaluation, Strategy
from .spec import Space
from .status import SearchStatus
from .uncertainty import Robust

HISTORY_SECONDS = 1.0  # how often a running search saves its history
MAX_REJECTED = 1000  # infeasible points in a row after which a search gives up asking


def reduce_over_scenarios(values: Iterable[float], how: str) -> float:
    array = np.asarray(list(values), dtype=float)
    return float({"sum": np.sum, "mean": np.mean, "max": np.max, "min": np.min}[how](array))


Check = tuple[str, Callable[[Mapping[str, float]], bool]]  # a ranking constraint's text and its test


def over_draws(
    per: Mapping[str, Mapping[str, float]],
    scalar: list[str],
    how: str,
    ranked: tuple[str, str, Robust | None],
) -> dict[str, float]:
    """A point's values from its sampled scenarios' (uncertainty.py): each draw reduced over the scenarios,
    then each objective's mean over the draws; the ranking objective ``ranked`` (name, goal, robust) its
    robust figure when the ranking asks for one, so a search optimises what the ranking ranks by."""
    draws: dict[int, dict[str, list[float]]] = {}
    for scenario, objectives in per.items():
        k = uncertainty.split_name(scenario)[1]
        for name in scalar:
            draws.setdefault(k, {}).setdefault(name, []).append(objectives[name])
    values = {
        name: np.array([reduce_over_scenarios(d[name], how) for d in draws.values()]) for name in scalar
    }
    objective, goal, robust = ranked
    return {
        name: uncertainty.robust_of(v, robust if name == objective else None, goal)
        for name, v in values.items()
    }


def evaluation_of(
    scores: list[TaskScores],
    scalar: list[str],
    how: str,
    checks: Sequence[Check] = (),
    ranked: tuple[str, str, Robust | None] | None = None,
) -> Evaluation:
    """A point's evaluation from its tasks: failed if any task failed, else each objective reduced, and
    the ranking constraints (``checks``) those values break, which constrained strategies learn from.
    Reduced in scenario-name order, whatever order the tasks came in: a sum's last bit depends on the order,
    and a reproducible search must tell the same numbers whether they come from workers or the store."""
    scores = sorted(scores, key=lambda s: s.scenario)
    failed = [s for s in scores if s.objectives is None]
    if failed:
        return Evaluation("failed", error=f"{failed[0].scenario}: {failed[0].error}")
    per = {s.scenario: s.objectives for s in scores}
    if ranked is not None:  # sampled scenarios: statistics over the draws
        values = over_draws(per, scalar, how, ranked)
        means = over_draws(
            per, scalar, how, (ranked[0], ranked[1], None)
        )  # constraints act on the means, as in rank
    else:
        values = means = {
            name: reduce_over_scenarios((o[name] for o in per.values()), how) for name in scalar
        }
    return Evaluation(
        "ok", values=values, scores=per, breaks=tuple(text for text, holds in checks if not holds(means))
    )


class SearchSource:
    """The chunks of a search, one per asked point, for sweep.Run to keep in flight."""

    def __init__(self, space: Space, shipment: str, status: SearchStatus):
        self.space = space
        self.shipment = shipment
        self.status = status
        self.scalar = [n for n, o in space.objectives.items() if not is_vector(o)]
        ranking = space.spec.ranking
        self.ranked = (ranking.objective, ranking.goal, ranking.robust) if space.draws is not None else None
        self.checks: list[Check] = [
            (text, compile_constraint(text, set(self.scalar), "objective"))
            for text in space.spec.ranking.constraints
        ]
        self.schema = store.results_schema(space.parameters, space.objectives)
        self.hashes = {s.name: scenario_hash(s) for s in space.scenarios}
        self.strategy: Strategy | None = None
        self.history: SearchHistory | None = None
        self.stored: dict[str, TaskScores] = {}
        self.requeue: deque[int] = deque()  # points to (re)submit before asking for new ones
        self.running: dict[int, dict[str, TaskScores]] = {}  # point number -> its task results so far
        self.followers: dict[
            int, list[int]
        ] = {}  # a running point -> later asks of the same point, told with it
        self.reproducible = space.spec.search.order == "reproducible"
        self.waiting: deque[int] = deque()  # reproducible: points asked and not yet told, in ask order
        self.ready: dict[
            int, tuple[Evaluation, bool]
        ] = {}  # ... of which these have their result (and reused)
        self.earlier: SearchHistory | None = (
            None  # reproducible: the last submission's, which it should repeat
        )
        self.wants_results = False  # reproducible: the strategy asked nothing until told more
        self.started = self.first_sent = 0.0
        self.saved = 0.0
        self.batch = 1
        self.told: set[tuple] = set()  # points told a simulation result: asking one again is a repeat
        self.rejected_in_a_row = 0
        self.stopping = False
        self.replaying = False  # the history is not saved while it is replayed

    # ---- starting and replaying ----------------------------------------------------------------

    def start(self, client, done: store.TaskIds) -> None:
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
        self.history = SearchHistory(
            sweep=self.space.name, strategy=self.space.spec.search.strategy, settings=settings
        )
        if self.reproducible and self.space.spec.search.batch is None and self.batch < threads:
            self.status.notes.append(
                f"a reproducible search asks {self.batch} points ahead unless search.batch says "
                f"otherwise, fewer than the cluster's {threads} worker threads: set search.batch "
                f"to {threads} or more to use them all (another batch asks other points)"
            )
        if old is not None and old.settings != settings:
            self.status.notes.append(
                "the search settings changed since the last submission: a new search; "
                "points already simulated are reused when asked again"
            )
        elif old is not None and old.points and self.reproducible:
            self.earlier, self.status.replayed = old, True  # asked again from the start, told from the store
        elif old is not None and old.points:
            self._replay(old, threads)

    def _settings(self) -> str:
        """What the points depend on; a reproducible search's also on its batch (the points asked ahead)."""
        spec = self.space.spec
        batch = self.batch if self.reproducible else None
        return settings_digest(
            spec.search.strategy,
            spec.search.seed,
            spec.search.options,
            [d.__dict__ for d in self.space.dimensions],
            spec.constraints,
            spec.ranking.model_dump(),
            self.space.model_key,
            sorted(self.hashes.values()),
            spec.search.order,
            batch,
        )

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
                point = self._strategy_ask()
                if point != asked.point or self.history.ask(point) != asked.number:
                    return self._afresh(
                        threads,
                        f"replaying the history, the strategy asked {point} where it had asked {asked.point}",
                    )
                continue
            evaluation = (
                self._from_store(asked.point) if asked.state != "infeasible" else Evaluation("infeasible")
            )
            if evaluation is None:
                return self._afresh(threads, f"the results of {asked.point} are no longer in the store")
            self._tell(asked.number, evaluation, reused=True)
        self.requeue.extend(self.history.outstanding())
        self.status.replayed = True

    def _afresh(self, threads: int, why: str) -> None:
        self.status.notes.append(
            f"could not replay the search ({why}): a new search; points already "
            "simulated are reused when asked again"
        )
        self.strategy = self.space.strategy(threads)
        self.history = SearchHistory(
            sweep=self.space.name, strategy=self.history.strategy, settings=self.history.settings
        )
        self.status.points = self.status.failed = self.status.infeasible = self.status.repeats = 0
        self.status.best = self.status.best_point = None
        self.told.clear()

    def _stored_scores(self) -> dict[str, TaskScores]:
        """Every stored task result of the current model, by task id."""
        columns = ["model", "status", "error", *self.space.objectives]
        rows = store.read_results(self.space.output, self.space.name, columns)
        rows = rows[rows["model"] == self.space.model_key]
        names = list(self.space.objectives)
        return {
            r["task_id"]: TaskScores(
                r["task_id"],
                r["scenario"],
                {n: _plain(r[n]) for n in names} if r["status"] == "ok" else None,
                r["error"],
            )
            for r in rows.to_dict("records")
        }

    # ---- the run's side: next chunk, finished chunk -----------------------------------------------

    def next(self, in_flight: int) -> ChunkJob | None:
        while self.requeue:  # in flight when the scheduler restarted, or when the last submission stopped
            job = self._job(self.requeue.popleft())
            if job is not None:
                return job
        return self._next_in_order() if self.reproducible else self._next_as_they_come(in_flight)

    def _next_as_they_come(self, in_flight: int) -> ChunkJob | None:
        """Asynchronous: ask while fewer than ``batch`` points are in flight
        (results are told as they come)."""
        while in_flight < self.batch and not self._should_stop():
            number = self._ask()
            if number is None:
                self.status.stopped = self.status.stopped or ("strategy" if not self.running else None)
                return None
            job = self._job(number)
            if job is not None:
                return job
        return None

    def _next_in_order(self) -> ChunkJob | None:
        """Reproducible: before asking, tell the oldest waiting point if ``batch`` points wait, or if the
        strategy asked for results (it asked nothing); its result not in yet, wait for it. So point n is
        always asked right after the tells of points 0 .. n - batch, whichever finished first. When the
        search stops, the rest is told in order as it comes."""
        while not self._should_stop():
            if len(self.waiting) >= self.batch or self.wants_results:
                if not self._tell_oldest():
                    return None
                self.wants_results = False
                continue
            number = self._ask()
            if number is None:
                if not self.waiting and not self.stopping:
                    self.status.stopped = self.status.stopped or "strategy"
                    return None
                self.wants_results = True
                continue
            self.waiting.append(number)
            job = self._job(number)
            if job is not None:
                return job
        while self._tell_oldest():
            pass
        return None

    def _tell_oldest(self) -> bool:
        """Tell the point asked first among those waiting, if its result is in."""
        if not self.waiting or self.waiting[0] not in self.ready:
            return False
        number = self.waiting.popleft()
        self._tell(number, *self.ready.pop(number))
        return True

    def _ask(self) -> int | None:
        """The number of the next point to evaluate; None when the strategy waits for results or has no more
        (or too many were rejected). Points the constraints reject are told as infeasible at once: the same
        in any order."""
        while not self._should_stop():
            point = self._strategy_ask()
            if point is None:
                return None
            number = self.history.ask(point)
            self._compare(number, point)
            if self.space.admits(point):
                self.rejected_in_a_row = 0
                return number
            self._tell(number, Evaluation("infeasible"), reused=False)
            self.rejected_in_a_row += 1
            if self.rejected_in_a_row >= MAX_REJECTED:
                self.status.stopped = "infeasible"
                self.status.notes.append(
                    f"the strategy proposed {MAX_REJECTED} points in a row that the "
                    "constraints reject; loosen them or narrow the parameters' ranges"
                )
                self.stopping = True
        return None

    def _strategy_ask(self) -> Point | None:
        """The strategy's next point, its time counted: the client's share of a search's time."""
        started = time.perf_counter()
        try:
            return self.strategy.ask()
        finally:
            self.status.ask_seconds += time.perf_counter() - started

    def _compare(self, number: int, point: Point) -> None:
        """Note once if a reproducible search asks other points than its last submission did with the same
        settings (a strategy that is not deterministic, or another version of its library)."""
        earlier = self.earlier
        if earlier is None or number >= len(earlier.points) or earlier.points[number].point == point:
            return
        self.status.notes.append(
            f"asked {point} as point {number} where the last submission asked "
            f"{earlier.points[number].point}: the strategy is not reproducible here; points "
            "already simulated are reused when asked again"
        )
        self.earlier = None

    def _should_stop(self) -> bool:
        status, search = self.status, self.space.spec.search
        if self.stopping:
            return True
        if status.points + self._open() >= search.max_points:
            status.stopped = "budget"
            return True
        if status.repeats >= search.max_points:  # a converged strategy that only proposes what it has had
            status.stopped = "repeats"
            return True
        if search.max_seconds is not None and time.monotonic() - self.started >= search.max_seconds:
            status.stopped = "time"
            return True
        return False

    def _open(self) -> int:
        """Points asked, not yet told, that will count against the budget when told. A reproducible search
        counts those waiting, finished or not, so that where it stops does not depend on timing."""
        if not self.reproducible:
            return len(self.running)
        keys = {tuple(sorted(self.history.points[n].point.items())) for n in self.waiting}
        return len(keys - self.told)

    def tasks(self, point: Point) -> list[Task]:
        ordered = tuple(sorted(point.items()))
        return [
            Task(task_id(self.space.model_key, point, self.hashes[s.name]), s.name, ordered)
            for s in self.space.scenarios
        ]

    def _job(self, number: int) -> ChunkJob | None:
        """The chunk of a point's tasks that have no row yet; None (and told now) if all have one."""
        point = self.history.points[number].point
        tasks = self.tasks(point)
        known = {t.task_id: self.stored[t.task_id] for t in tasks if t.task_id in self.stored}
        missing = [t for t in tasks if t.task_id not in known]
        if not missing:
            self._done(
                number,
                evaluation_of(list(known.values()), self.scalar, self._how(), self.checks, self.ranked),
                reused=True,
            )
            return None
        leader = next((n for n in self.running if self.history.points[n].point == point), None)
        if leader is not None:  # asked again while it runs (a discrete space): told when it finishes
            self.followers.setdefault(leader, []).append(number)
            return None
        self.running[number] = known
        if not self.first_sent:
            self.first_sent = time.monotonic()
        space, batch = self.space, TaskBatch.of(missing)
        return ChunkJob(
            space.name,
            chunk_id_of(batch),
            self.shipment,
            space.model_key,
            batch,
            space.objectives,
            space.output,
            self.schema,
            space.spec.timeout,
            space.experiment,
            with_scores=True,
            point=number,
        )

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
            self._done(
                job.point,
                evaluation_of(list(results.values()), self.scalar, self._how(), self.checks, self.ranked),
                reused=False,
            )

    def _how(self) -> str:
        return self.space.spec.ranking.over_scenarios

    def _from_store(self, point: Point) -> Evaluation | None:
        tasks = self.tasks(point)
        if not all(t.task_id in self.stored for t in tasks):
            return None
        return evaluation_of(
            [self.stored[t.task_id] for t in tasks], self.scalar, self._how(), self.checks, self.ranked
        )

    def _done(self, number: int, evaluation: Evaluation, reused: bool) -> None:
        """A point's result (and so its followers'): told now if asynchronous; if reproducible, kept until its
        turn (_next_in_order)."""
        if self.reproducible:
            self.ready[number] = (evaluation, reused)
        else:
            self._tell(number, evaluation, reused)
        for follower in self.followers.pop(number, []):
            self._done(follower, evaluation, reused=True)

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
            better = status.best is None or (
                value < status.best if status.goal == "min" else value > status.best
            )
            if better or (value == status.best and _sorts_first(point, status.best_point)):
                status.best, status.best_point = value, dict(point)
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


def _sorts_first(point: Point, other: Point | None) -> bool:
    """Of two points with equal objectives, the one rank() names best: the first by parameter values (its
    totals are grouped by them, in the space's order), so the search's best and the ranking's agree."""
    try:
        return other is not None and tuple(point.values()) < tuple(other[name] for name in point)
    except (TypeError, KeyError):  # mixed value types: keep the first found
        return False
