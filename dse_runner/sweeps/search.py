"""Search strategies: which parameter points a sweep visits, as ask/tell plug-ins.

A strategy is a class built from a :class:`Problem` (the dimensions, the
objectives to optimise, the budget and its own options). The runner *asks*
it for points ahead of their results and *tells* it each point's
:class:`Evaluation` when the point's simulations finish (by default in the
order the points were asked: closed_loop.py), the way Optuna's
``study.ask``/``study.tell`` work. A strategy never simulates anything, so the
same strategy runs on a laptop or a cluster. Given its seed and the same
sequence of asks and tells, it must ask the same points: that is what makes a
search reproducible and lets a later submission go on from the stored results.

``exhaustive`` is the grid strategy: it asks every point up front without
needing results (``closed_loop = False``), and the sweep runs it in large
chunks. The others (strategies/) wrap Optuna, scipy and pymoo. More plug in
without touching this module, the way ``distributed`` takes plug-ins: a
package declares an entry point in the group ``dse_runner.search``, as
dse-runner's own pyproject.toml declares the built-in ones::

    [project.entry-points."dse_runner.search"]
    my_search = "my_package.search:MySearch"   # a subclass of dse_runner.sweeps.search.Strategy
"""

from __future__ import annotations

import itertools
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, PositiveFloat, PositiveInt, ValidationError

from .. import plugins
from ..errors import DseError, did_you_mean
from ..schema import Extensible, Strict
from .domain import Dimension, Point


@dataclass(frozen=True)
class Problem:
    """What a strategy is told about the search before it starts."""

    label: str  # the sweep's name, for messages
    dimensions: tuple[Dimension, ...]
    objective: tuple[str, str]  # (name, "min" | "max"): the ranking objective
    pareto: tuple[tuple[str, str], ...]  # the ranking's Pareto objectives, for multi-objective strategies
    scenarios: tuple[str, ...]
    vectors: tuple[str, ...]  # objectives that give one number per sample (least squares fits them)
    max_points: int
    seed: int
    batch: int  # points asked ahead of their results (asked and not yet told) at most
    options: Mapping[str, Any] = field(default_factory=dict)  # the strategy's own, from space.yaml's search:
    admits: Callable[[Point], bool] = lambda point: True  # the spec's constraints
    constrained: bool = False  # whether ``admits`` can refuse a point


@dataclass(frozen=True)
class Evaluation:
    """What became of one asked point."""

    state: Literal["ok", "failed", "infeasible"]  # infeasible: the constraints reject it; never simulated
    values: Mapping[str, float] = field(default_factory=dict)  # each scalar objective reduced over scenarios
    scores: Mapping[str, Mapping[str, Any]] = field(
        default_factory=dict
    )  # scenario -> objective -> value (ok tasks)
    error: str | None = None
    breaks: tuple[str, ...] = ()  # ok, but these ranking constraints on its objectives fail: ranked never

    @property
    def feasible(self) -> bool:
        """Simulated, and within the ranking's constraints: a point the ranking may choose."""
        return self.state == "ok" and not self.breaks

    def value(self, name: str) -> float:
        return self.values[name]


class Options(BaseModel):
    """A strategy's own options (keys under ``search:`` besides the common ones); none by default."""

    model_config = ConfigDict(**Strict, populate_by_name=True)


class BudgetWarning(UserWarning):
    """A search that will run well under its budget: how many points it runs, and how to get more."""


class Strategy(ABC):
    """Ask for points, be told how they did: the contract of ``search.strategy`` and of the plug-ins in
    the entry-point group ``dse_runner.search``, which name a subclass.

    Lifecycle. The class is constructed with a :class:`Problem`, on the client: once when the space
    is read (so that what only the constructor checks fails before a cluster starts; that instance is
    dropped), then once per submission of a search (a grid: once per pass over its points, to count
    them and to send them). ``problem.options`` (the keys under ``search:`` besides the common ones)
    arrive validated as ``self.options``, an instance of the class's ``Options`` model. Then the
    runner alternates :meth:`ask` and :meth:`tell` until the budget (``max_points``, ``max_seconds``)
    is spent or the strategy has no more points (a grid is only asked, never told):

    - :meth:`ask` returns the next point (``instance.variable`` -> value) or None. None means "wait":
      nothing until a result is told, or nothing more at all; the search ends when the strategy
      answers None with no point left in flight. At most ``problem.batch`` points are asked and not
      yet told; a strategy that needs a whole generation told before it breeds the next answers None
      meanwhile.
    - :meth:`tell` gives each asked point's :class:`Evaluation`, exactly once, by default in the order
      the points were asked (``search.order: reproducible``; closed_loop.py), else as results come.
      A point the constraints (``problem.admits``) reject is told infeasible at once, never simulated.

    Given ``problem.seed`` and the same sequence of asks and tells, a strategy must ask the same
    points: that is what makes a search reproducible and lets a later submission replay the stored
    results instead of simulating them again. A strategy never simulates anything itself.

    Optional parts, with defaults that do nothing: :meth:`tell` (ignored: a strategy that learns
    nothing from results), ``Options`` (no options of its own), ``size`` (unknown), :meth:`spending` (silent),
    ``closed_loop`` (True; False: a grid, whose points are all known without results and which the
    sweep runs in large chunks), ``budgeted`` (True; False: ``max_points`` and ``seed`` chose none of its
    points, so a report leaves them out), ``multi_objective`` (False; True: it optimises the ranking's
    Pareto objectives, and the space must list two or more)."""

    closed_loop: ClassVar[bool] = True  # False: every point is known without results (a grid)
    budgeted: ClassVar[bool] = True  # False: no budget or seed chose its points (a grid, a caller's points)
    multi_objective: ClassVar[bool] = False  # optimises the ranking's Pareto objectives
    Options: ClassVar[type[BaseModel]] = Options

    size: int | None = None  # open loop: how many points it will ask, where known without asking them

    def spending(self) -> str | None:
        """One line when the strategy will ask well under its budget (``max_points``), saying how many
        distinct points it runs and how to get more; None when it uses its budget or cannot know."""
        return None

    def __init__(self, problem: Problem):
        self.problem = problem
        self.options = parse_options(type(self), problem.options)

    @abstractmethod
    def ask(self) -> Point | None:
        """The next point to evaluate; None when there is none for now (waiting for results) or any more."""

    def tell(self, point: Point, evaluation: Evaluation) -> None:
        """How an asked point did; strategies that learn nothing from results ignore it."""


def parse_options(kind: type[Strategy], options: Mapping[str, Any]) -> BaseModel:
    try:
        return kind.Options.model_validate(dict(options))
    except ValidationError as e:
        problem = e.errors()[0]
        where = ".".join(str(p) for p in problem["loc"])
        raise DseError(
            f"search.{where}: {problem['msg'][:1].lower()}{problem['msg'][1:]} (an option of {kind.__name__})"
        ) from None


class Exhaustive(Strategy):
    """Every combination of the parameters' values that satisfies the constraints."""

    closed_loop = False
    budgeted = False

    def __init__(self, problem: Problem):
        super().__init__(problem)
        continuous = [d.name for d in problem.dimensions if d.grid() is None]
        if continuous:
            raise DseError(
                f"search: exhaustive needs a list or a grid {{start, stop, step}} for every parameter; "
                f"{', '.join(continuous)} is an interval {{low, high}}: give a grid, or a search "
                "strategy such as tpe"
            )
        names = [d.name for d in problem.dimensions]
        grids = [d.grid() for d in problem.dimensions]
        combinations = itertools.product(*grids)
        if problem.constrained:
            admits = problem.admits
            self._points: Iterator[Point] = (p for v in combinations if admits(p := dict(zip(names, v))))
        else:  # a large grid: one generator, and its size without walking it
            self._points = (dict(zip(names, v)) for v in combinations)
            self.size = math.prod(len(g) for g in grids)

    def ask(self) -> Point | None:
        return next(self._points, None)


class Given(Strategy):
    """No points of its own: a caller gives every point (fit.py's rounds, a diagnosis's fits), so the
    parameters may take any form, intervals included. Submitted without points, it runs nothing."""

    closed_loop = False
    budgeted = False
    size = 0

    def ask(self) -> Point | None:
        return None


GROUP = "dse_runner.search"  # the built-in strategies are its entries too (pyproject.toml): Optuna, pymoo and
# torch are imported only when a strategy that needs them is chosen


def available() -> dict[str, str]:
    """Strategy name -> import path: the built-in ones and those installed packages declare."""
    return {name: entry.value for name, entry in plugins.entries(GROUP).items()}


def strategy(name: str) -> type[Strategy]:
    """The strategy class of ``name``; importing it only now."""
    label = f"search strategy {name!r}"
    found = plugins.load(GROUP, name, label)
    if found is None:
        raise DseError(
            f"unknown search strategy {name!r}{did_you_mean(name, plugins.names(GROUP))}: available are "
            f"{', '.join(plugins.names(GROUP))}"
        )
    return plugins.subclass_of(found, Strategy, label, plugins.entries(GROUP)[name].value)


def points(make: Callable[[], Strategy]) -> Iterator[Point]:
    """Every point an open-loop strategy asks for."""
    chosen = make()
    return iter(chosen.ask, None)


def count(make: Callable[[], Strategy]) -> int:
    """How many points an open-loop strategy asks for: its ``size``, else by asking them all."""
    chosen = make()
    return chosen.size if chosen.size is not None else sum(1 for _ in iter(chosen.ask, None))


BATCH = (
    4  # a reproducible search's points asked ahead: fixed, so that the points do not depend on the cluster
)


class Search(BaseModel):
    """How points are chosen (search.py). Keys besides these are the strategy's own options."""

    model_config = Extensible
    strategy: str = "exhaustive"  # built-in or a plug-in's (see search.py)
    max_points: PositiveInt = 100  # a search stops after this many simulated points (not for exhaustive)
    max_seconds: PositiveFloat | None = None  # ... or when this submission has run this long
    seed: int = 0  # with order: reproducible, the same seed and spec give the same points
    # reproducible: each result is told once every point asked before it has been told, and a point is
    # asked only while fewer than ``batch`` points wait for theirs: the points depend on no worker's timing.
    # asynchronous: each result is told as it comes (closed_loop.py).
    order: Literal["reproducible", "asynchronous"] = "reproducible"
    batch: PositiveInt | None = (
        None  # points asked ahead of their results; default BATCH, or threads + 1 if asynchronous
    )

    @property
    def options(self) -> dict[str, Any]:
        return dict(self.model_extra or {})


def batch_of(search: Search, threads: int) -> int:
    """Points asked ahead of their results: a reproducible search's may not depend on the cluster (it would
    change the points); an asynchronous one keeps every worker thread busy and one point waiting."""
    if search.batch is not None:
        return search.batch
    return threads + 1 if search.order == "asynchronous" else BATCH
