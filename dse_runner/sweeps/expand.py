"""Expansion of a design space into (parameter point, scenario) tasks with stable ids.

A task id is a hash of what determines its result: the model (the FMUs'
contents, the multi-model's wiring and values, the objectives), the point's
values, and the scenario's recorded data. The same task therefore has the
same id in every run, which is what lets a re-run skip finished work, and a
changed FMU or recording gives new ids instead of stale results.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Callable, Collection, Iterable, Iterator
from dataclasses import dataclass
from json.encoder import encode_basestring_ascii
from typing import Any

import numpy as np

from ..simulation import objectives as objs
from ..simulation.fmu import content_hash
from ..simulation.plan import Plan
from ..simulation.scenario import Scenario
from ..simulation.trajectory import Series
from .domain import Point
from .search import count as count_points
from .search import points as search_points
from .store import TaskIds


@dataclass(frozen=True)
class Task:
    task_id: str
    scenario: str
    point: tuple[tuple[str, Any], ...]  # sorted (name, value) pairs: hashable and picklable


_CANONICAL = json.JSONEncoder(
    sort_keys=True, default=str, separators=(",", ":")
)  # made once: ids of 100,000s


def _digest(*parts: Any) -> str:
    return hashlib.sha256(_CANONICAL.encode(parts).encode()).hexdigest()


def model_hash(
    plan: Plan,
    objectives: dict[str, objs.ObjectiveSpec],
    experiment: Any = None,
    uncertain: dict[str, Any] | None = None,
    modules: dict[str, bytes] | None = None,
) -> str:
    """What the model is, independent of where its files lie: FMUs, wiring, experiment, objectives (the
    sources of a user's objective modules too: an edited one scores anew), and what fixes an uncertain
    sample's draws (uncertainty.identity)."""
    mm = plan.multimodel.model_dump(mode="json", exclude={"fmus", "base_dir"})
    if mm.get("step_sizes") == "difference":  # the default, as before the key existed: older stores resume
        del mm["step_sizes"]
    fmus = {name: content_hash(path) for name, path in sorted(plan.fmu_paths.items())}
    scored = {
        name: spec if isinstance(spec, str) else spec.model_dump(mode="json")
        for name, spec in objectives.items()
    }
    times = experiment.model_dump(mode="json", exclude_none=True) if experiment is not None else {}
    sources = {name: hashlib.sha256(source).hexdigest() for name, source in sorted((modules or {}).items())}
    return _digest(
        fmus,
        mm,
        scored,
        *([times] if times else []),
        *([uncertain] if uncertain else []),
        *([sources] if sources else []),
    )[:32]


def scenario_hash(scenario: Scenario) -> str:
    """What a scenario is: its settings and the contents of every file it was read from."""
    settings = {
        "kind": scenario.kind,
        "group": scenario.group,
        "parameters": dict(scenario.parameters),
        "fields": dict(scenario.fields),
        "options": dict(scenario.options),
        "inputs": {ref: "series" if isinstance(v, Series) else v for ref, v in scenario.inputs.items()},
        "times": [scenario.start_time, scenario.stop_time, scenario.step, scenario.natural_step],
    }
    return _digest(settings, [content_hash(path) for path in scenario.sources])[:32]


def task_id(model: str, point: Point, scenario: str) -> str:
    names = tuple(sorted(point))
    return _ids(model, names, [[point[name] for name in names]], scenario)[0]


_NUMBERS: dict[type, Callable[[Any], str]] = {  # plain numbers as the json module writes them
    float: lambda v: (
        float.__repr__(v)
        if math.isfinite(v)
        else "NaN"
        if math.isnan(v)
        else "Infinity"
        if v > 0
        else "-Infinity"
    ),
    int: int.__repr__,
    bool: lambda v: "true" if v else "false",
}


def _ids(model: str, names: tuple[str, ...], rows: list[list[Any]], data: str) -> list[str]:
    """The id of each row of values (in ``names``' order, sorted): ``_digest(model, pairs, data)[:24]``.
    When every value is a plain number the JSON is written directly, a column at a time: the same text
    (tests/sweeps/test_sweep.py checks), for a fraction of the cost, and a large sweep hashes 100,000s."""
    columns = []
    for k, name in enumerate(names):
        quoted = encode_basestring_ascii(name)
        try:
            columns.append([f"[{quoted},{_NUMBERS[type(row[k])](row[k])}]" for row in rows])
        except KeyError:  # a string or other value: the json module writes it
            return [_digest(model, tuple(zip(names, row)), data)[:24] for row in rows]
    head, tail = f"[{encode_basestring_ascii(model)},[", f"],{encode_basestring_ascii(data)}]"
    parts = zip(*columns) if columns else [()] * len(rows)
    sha = hashlib.sha256
    return [sha(f"{head}{','.join(row)}{tail}".encode()).hexdigest()[:24] for row in parts]


def points_of(space, points: list[Point] | None = None) -> Callable[[Any], Iterable[Point]]:
    """The space's grid strategy's points, or the given points (a search strategy's)."""
    return (lambda s: search_points(s.strategy)) if points is None else (lambda _: points)


def expand(
    space, points: list[Point] | None = None, only: list[Collection[str]] | None = None
) -> Iterator[Task]:
    """Tasks scenario by scenario, so a chunk of consecutive tasks mostly shares one scenario.

    ``only`` (with ``points``) names, for each point, the scenarios it is wanted on: an
    optimiser fitting some runs need not simulate the others. Without it, every point
    runs on every scenario."""
    for block in blocks(space, points, only):
        yield from block


BLOCK = 1024  # points hashed together: large enough that per-block costs vanish, small enough to stream


Key = tuple[tuple[str, float], ...]


def key_of(point: Point) -> Key:
    return tuple(sorted(point.items()))


def wanted(requests: Iterable[tuple[Point, Iterable[str]]]) -> tuple[list[Point], list[set[str]]]:
    """Distinct points, each with the union of the scenarios asked of it.

    A fit on some runs (a cross-validation fold) needs its points simulated on those runs
    only; fits that ask for the same point share its simulations."""
    by_key: dict[Key, tuple[Point, set[str]]] = {}
    for point, scenarios in requests:
        by_key.setdefault(key_of(point), (point, set()))[1].update(scenarios)
    return [p for p, _ in by_key.values()], [s for _, s in by_key.values()]


def distinct(
    points: list[Point], only: list[Collection[str]] | None
) -> tuple[list[Point], list[Collection[str]] | None]:
    """The given points less repeats (with the union of the scenarios asked of each): a point asked twice
    is simulated once and answers both asks, whose rows are found by the point."""
    if only is None:
        unique: dict[Key, Point] = {}
        for point in points:
            unique.setdefault(key_of(point), point)
        return list(unique.values()), None
    return wanted(zip(points, only))


def blocks(
    space,
    points: list[Point] | None = None,
    only: list[Collection[str]] | None = None,
    done: TaskIds | None = None,
) -> Iterator[TaskBatch]:
    """expand()'s tasks in batches of up to BLOCK, less those in ``done``. A sweep makes its chunks from
    these: ids are written a column at a time, so a 100,000-task sweep's client keeps up with its workers."""
    if only is not None and (points is None or len(only) != len(points)):
        raise ValueError("expand: `only` needs one collection of scenario names per given point")
    model = space.model_key
    visit = points_of(space, points)
    for scenario in space.scenarios:
        data = scenario_hash(scenario)
        wanted = iter(
            (p for k, p in enumerate(visit(space)) if scenario.name in only[k])
            if only is not None
            else visit(space)
        )  # regenerated per scenario: no list of all points is kept
        while block := list(itertools.islice(wanted, BLOCK)):
            batches = (
                TaskBatch.of_points(model, same, scenario.name, data)
                for same in (_alike(block) if points is not None else (block,))
            )  # a grid's are alike
            yield from undone(batches, done)


def undone(batches: Iterable[TaskBatch], done: TaskIds | None) -> Iterator[TaskBatch]:
    """Each batch less its tasks in ``done``; batches left empty are dropped."""
    for batch in batches:
        if done:
            batch = batch[~done.among(batch.task_ids)]
        if len(batch):
            yield batch


def tally(batches: Iterable[TaskBatch], done: TaskIds | None) -> tuple[int, int]:
    """(tasks, tasks with a row in ``done``) of batches made already."""
    total = finished = 0
    for batch in batches:
        total += len(batch)
        finished += int(done.among(batch.task_ids).sum()) if done else 0
    return total, finished


def _alike(points: list[Point]) -> Iterator[list[Point]]:
    """Consecutive runs of points that set the same parameters, in order: a batch's values are one table.
    A fit may ask for points of differing parameters in one sweep (a probe that sets one more)."""
    first = points[0].keys()
    if all(point.keys() == first for point in points):  # the usual case: one table, no regrouping
        yield points
        return
    for _, run in itertools.groupby(points, key=dict.keys):  # key views compare as sets, in C
        yield list(run)


def count(
    space, done: TaskIds | None, points: list[Point] | None = None, only: list[Collection[str]] | None = None
) -> tuple[int, int]:
    """(tasks, tasks with a row in ``done``): ids are computed only if some tasks are done, since
    hashing every task of a large fresh sweep would keep the workers waiting for the client."""
    if done:
        return tally(blocks(space, points, only), done)
    if only is not None:
        return sum(scenario.name in wanted for scenario in space.scenarios for wanted in only), 0
    return (len(points) if points is not None else count_points(space.strategy)) * len(space.scenarios), 0


@dataclass(frozen=True)
class TaskBatch:
    """A chunk of tasks stored as columns: ~40 bytes a task instead of ~900 as objects.

    Dask's scheduler keeps a submitted task's arguments for a while after it
    finishes; with compact batches that bookkeeping stays small even for
    100,000-task sweeps."""

    parameters: tuple[str, ...]
    scenarios: tuple[str, ...]
    task_ids: np.ndarray  # fixed-width bytes
    scenario_index: np.ndarray  # into ``scenarios``
    values: np.ndarray  # tasks x parameters; float64 when every value is a float

    @classmethod
    def of(cls, tasks: list[Task]) -> TaskBatch:
        parameters = tuple(name for name, _ in tasks[0].point)
        scenarios = tuple(dict.fromkeys(t.scenario for t in tasks))
        index = {name: k for k, name in enumerate(scenarios)}
        return cls(
            parameters,
            scenarios,
            np.array([t.task_id.encode() for t in tasks]),
            np.array([index[t.scenario] for t in tasks], dtype=np.int32),
            _values([value for t in tasks for _, value in t.point], len(tasks), len(parameters)),
        )

    @classmethod
    def of_points(cls, model: str, points: list[Point], scenario: str, data: str) -> TaskBatch:
        """The tasks of ``points`` on one scenario (``data``: its hash), ids as ``task_id`` gives them. Every
        point sets the same parameters (:func:`blocks` groups them so)."""
        names = tuple(sorted(points[0]))
        rows = [[point[name] for name in names] for point in points]
        ids = _ids(model, names, rows, data)
        return cls(
            names,
            (scenario,),
            np.array([i.encode() for i in ids]),
            np.zeros(len(rows), dtype=np.int32),
            _values([v for row in rows for v in row], len(rows), len(names)),
        )

    @classmethod
    def concat(cls, batches: list[TaskBatch]) -> TaskBatch:
        """One batch of several that set the same parameters."""
        if len(batches) == 1:
            return batches[0]
        scenarios = tuple(dict.fromkeys(name for b in batches for name in b.scenarios))
        index = {name: k for k, name in enumerate(scenarios)}
        remap = [
            np.array([index[name] for name in b.scenarios], dtype=np.int32)[b.scenario_index] for b in batches
        ]
        values = [b.values for b in batches]
        kind = np.float64 if all(v.dtype == np.float64 for v in values) else object
        return cls(
            batches[0].parameters,
            scenarios,
            np.concatenate([b.task_ids for b in batches]),
            np.concatenate(remap),
            np.concatenate([v.astype(kind) for v in values]),
        )

    def __getitem__(self, which: slice | np.ndarray) -> TaskBatch:
        """Some of the tasks: a slice, or a boolean mask."""
        return TaskBatch(
            self.parameters,
            self.scenarios,
            self.task_ids[which],
            self.scenario_index[which],
            self.values[which],
        )

    def ids(self) -> list[str]:
        return self.task_ids.astype(str).tolist()

    def __len__(self) -> int:
        return len(self.task_ids)

    def __iter__(self) -> Iterator[Task]:
        names, parameters = self.scenarios, self.parameters
        for task_id, scenario, row in zip(self.ids(), self.scenario_index.tolist(), self._rows()):
            yield Task(task_id, names[scenario], tuple(zip(parameters, row)))

    def points(self) -> Iterator[tuple[str, Point]]:
        """(scenario, point) of each task: what a worker simulates, without a Task object per task."""
        names, parameters = self.scenarios, self.parameters
        for scenario, row in zip(self.scenario_index.tolist(), self._rows()):
            yield names[scenario], dict(zip(parameters, row))

    def _rows(self) -> list[list[Any]]:
        """The values with plain Python types (a float64 column's ``tolist`` gives floats)."""
        rows = self.values.tolist()
        if self.values.dtype == object:  # numpy scalars a strategy gave become plain values
            rows = [[v.item() if hasattr(v, "item") else v for v in row] for row in rows]
        return rows


def _values(flat: list[Any], n: int, width: int) -> np.ndarray:
    """Tasks x parameters: float64 when every value is a float, else the values themselves."""
    numeric = all(type(v) is float for v in flat)
    return np.array(flat, dtype=np.float64 if numeric else object).reshape(n, width)


def chunked(batches: Iterable[TaskBatch], size: int | Callable[[], int]) -> Iterator[TaskBatch]:
    """Batches of ``size`` tasks; a callable size is asked before each chunk, so a sweep can re-size its
    chunks from what the finished ones cost. A chunk holds points of one set of parameters: a batch that sets
    others starts a new chunk."""
    size_now = size if callable(size) else lambda: size
    parts: list[TaskBatch] = []
    have, wanted = 0, size_now()
    for batch in batches:
        if parts and batch.parameters != parts[0].parameters:
            yield TaskBatch.concat(parts)
            parts, have, wanted = [], 0, size_now()
        while len(batch):
            part, batch = batch[: wanted - have], batch[wanted - have :]
            parts.append(part)
            have += len(part)
            if have >= wanted:
                yield TaskBatch.concat(parts)
                parts, have, wanted = [], 0, size_now()
    if parts:
        yield TaskBatch.concat(parts)
