"""One contract, run over every search strategy, the way Optuna's test_samplers.py runs one test over every
sampler: the built-in ones and any that an installed package registers (entry-point group
``dse_runner.search``), each asked and told by an in-process loop that keeps the closed loop's rules
(sweeps/closed_loop.py, ``search.order: reproducible``) with a cheap analytic function in place of the
simulations: no Dask, no FMU. A strategy must ask only points of the domain, ask the same points for the same
seed, take failed and infeasible results and go on, and stop within the budget; a multi-objective one must
learn from every Pareto objective, and any other from the ranking's objective alone."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import pytest

from dse_runner.errors import DseError
from dse_runner.sweeps import search
from dse_runner.sweeps.domain import Dimension, Point
from dse_runner.sweeps.search import (
    BATCH,  # points asked ahead of their results: a reproducible search's
    Evaluation,
    Problem,
    Strategy,
)

# Read at collection: a plug-in installed later is in the next run. ``given`` asks nothing by design (its
# points come from a fit); test_fit.py runs it.
STRATEGIES = sorted(name for name in search.available() if name != "given")

# Every kind of parameter space.yaml can give (domain.py), each under its own name: an interval, a log
# interval, an integer interval, a stepped grid, and a list of choices (one of them text).
INTERVAL = Dimension("plant.x", low=-2.0, high=3.0)
LOG = Dimension("plant.y", low=0.01, high=10.0, log=True)
INTEGER = Dimension("plant.n", low=1.0, high=6.0, integer=True)
STEPPED = Dimension("plant.s", low=0.0, high=2.0, step=0.5)
CHOICES = Dimension("plant.mode", choices=(0.1, 0.4, "off"))
# The spaces tried in turn until a strategy takes one (its constructor raises DseError for what it cannot
# search: exhaustive needs grids, least_squares continuous intervals); each strategy must take one.
DOMAINS = {
    "mixed": (INTERVAL, LOG, INTEGER, STEPPED, CHOICES),
    "continuous": (INTERVAL, LOG),
    "grid": (INTEGER, STEPPED, CHOICES),
}
SCENARIOS = ("first", "second")
OBJECTIVE = ("f", "min")
PARETO = (("f", "min"), ("g", "min"))
FAIL_EVERY = 5  # every fifth point simulated fails, wherever it lies
# Strategies whose smallest design is larger than the budgets below, run with their smallest options at that
# design's size: eFAST needs more than 4 M^2 rows per curve, with M = 1 ten points over two parameters.
SMALLEST = {"fast": ({"harmonics": 1}, 10)}


def admits(point: Point) -> bool:
    """The space's constraints: two corners of the domain are out (where it has the parameters they judge)."""
    x, n, s = point.get("plant.x", 0.0), point.get("plant.n", 1.0), point.get("plant.s", 0.0)
    return not (x > 2.0 and n >= 5) and not (n == 6 and s >= 1.5)


def unit(d: Dimension, value) -> float:
    """Where ``value`` lies in its dimension, from 0 to 1 (choices: their position in the list)."""
    if d.choices is not None:
        return d.choices.index(value) / max(len(d.choices) - 1, 1)
    if d.log:
        return (math.log(value) - math.log(d.low)) / (math.log(d.high) - math.log(d.low))
    return (value - d.low) / (d.high - d.low)


def in_domain(d: Dimension, value) -> bool:
    if d.choices is not None:
        return value in d.choices
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not d.low <= value <= d.high:
        return False
    if d.step is not None:
        steps = (value - d.low) / d.step
        return abs(steps - round(steps)) < 1e-9
    return float(value).is_integer() if d.integer else True


@dataclass
class Run:
    """What one search did: its asks in order, its tells in order, and why it stopped."""

    asked: list[Point] = field(default_factory=list)
    told: list[tuple[Point, Evaluation]] = field(default_factory=list)
    asks_at_tell: list[int] = field(default_factory=list)  # how many points had been asked at each tell
    points: int = 0  # distinct points simulated and told (the budget counts these)
    stopped: str = ""


def evaluate(dimensions: tuple[Dimension, ...], point: Point, number: int) -> Evaluation:
    """The analytic stand-in for a point's simulations, one result per scenario: f is the squared distance
    from a target inside the domain (least squares fits its residuals), g the squared distance from the
    opposite corner; every FAIL_EVERY-th simulated point fails, and a g above its mean over the domain breaks
    a ranking constraint (simulated, then ranked never): about half the points."""
    if number % FAIL_EVERY == FAIL_EVERY - 1:
        return Evaluation("failed", error="first: fmi2DoStep returned fmi2Error")
    u = [unit(d, point[d.name]) for d in dimensions]
    residuals = [ui - 0.3 for ui in u]
    half = len(residuals) // 2
    per = {"first": residuals[:half], "second": residuals[half:]}
    scores = {
        s: {
            "f": sum(r * r for r in per[s]),
            "g": sum((1 - ui) ** 2 for ui in u) / len(SCENARIOS),
            "residuals": per[s],
        }
        for s in SCENARIOS
    }
    values = {name: sum(scores[s][name] for s in SCENARIOS) for name in ("f", "g")}  # over_scenarios: sum
    limit = len(dimensions) / 3  # the mean of (1 - u)² for u uniform in [0, 1] is 1/3
    breaks = (f"g <= {limit}",) if values["g"] > limit else ()
    return Evaluation("ok", values=values, scores=scores, breaks=breaks)


def drive(make: Callable[[], Strategy], problem: Problem) -> Run:
    """Ask and tell as the closed loop does in its reproducible order: ask while fewer than ``batch`` points
    wait for their results, tell the oldest when ``batch`` wait or the strategy asks nothing (None), tell a
    point the constraints reject as infeasible at once, tell a point asked again its result without counting
    it, and stop at the budget or when the strategy has nothing more with nothing waiting."""
    strategy, run = make(), Run()
    waiting: deque[Point] = deque()
    results: dict[tuple, Evaluation] = {}  # each distinct point's result: a repeat is told the same
    wants_results = False

    def key(point: Point) -> tuple:
        return tuple(sorted(point.items()))

    def tell(point: Point, evaluation: Evaluation) -> None:
        strategy.tell(point, evaluation)
        run.told.append((point, evaluation))
        run.asks_at_tell.append(len(run.asked))

    def tell_oldest() -> None:
        point = waiting.popleft()
        if key(point) not in results:
            results[key(point)] = evaluate(problem.dimensions, point, run.points)
            run.points += 1
        tell(point, results[key(point)])

    def open_points() -> int:
        return len({key(p) for p in waiting} - set(results))

    while True:
        assert len(run.asked) < 50 * problem.max_points, "it keeps asking: 50 asks per point of the budget"
        if run.points + open_points() >= problem.max_points:
            run.stopped = "budget"
            break
        if len(waiting) >= problem.batch or (wants_results and waiting):
            tell_oldest()
            wants_results = False
            continue
        point = strategy.ask()
        if point is None:
            if not waiting:
                run.stopped = "strategy"
                break
            wants_results = True
            continue
        run.asked.append(point)
        if not problem.admits(point):
            tell(point, Evaluation("infeasible"))
            continue
        waiting.append(point)
    while waiting:
        tell_oldest()
    return run


def problem_for(
    name: str, seed: int = 7, max_points: int = 14, pareto=PARETO
) -> tuple[type[Strategy], Problem]:
    """The strategy class of ``name`` and the first of DOMAINS it takes, as a Problem (as spec.py makes
    it)."""
    kind = search.strategy(name)
    options, least = SMALLEST.get(name, ({}, 0))
    refused = []
    for domain, dimensions in DOMAINS.items():
        problem = Problem(
            label="contract",
            dimensions=dimensions,
            objective=OBJECTIVE,
            pareto=pareto,
            scenarios=SCENARIOS,
            vectors=("residuals",),
            max_points=max(max_points, least),
            seed=seed,
            batch=BATCH,
            admits=admits,
            constrained=True,
            options=options,
        )
        try:
            kind(problem)
        except DseError as e:
            refused.append(f"{domain}: {e}")
            continue
        return kind, problem
    pytest.fail(f"{name} takes none of the domains: {refused}")


@pytest.mark.parametrize("name", STRATEGIES)
def test_every_strategy_asks_in_the_domain_the_same_points_for_its_seed_and_takes_every_result(name):
    kind, problem = problem_for(name)
    run = drive(lambda: kind(problem), problem)
    names = {d.name for d in problem.dimensions}
    assert run.asked, f"{name} asked no point"
    for point in run.asked:
        assert set(point) == names, point
        for d in problem.dimensions:
            assert in_domain(d, point[d.name]), f"{name} asked {d.name} = {point[d.name]!r}, outside {d}"
    assert run.points <= problem.max_points
    assert len(run.told) == len(run.asked)  # every asked point told once, none lost at the end

    states = [e.state if not e.breaks else "breaks" for _, e in run.told]
    assert "failed" in states, f"{name}'s search ended before any point failed: {states}"
    for state in ("failed", "infeasible", "breaks"):  # whichever came: the search goes on after the first
        if state in states:
            asked_after = len(run.asked) - run.asks_at_tell[states.index(state)]
            assert asked_after > 0 or run.stopped == "budget", (
                f"{name} asked nothing after a point told {state}: {run.points} of {problem.max_points}"
            )

    again = drive(lambda: kind(problem), problem)
    assert again.asked == run.asked, f"{name} asked other points for the same seed and the same results"


@pytest.mark.parametrize("name", STRATEGIES)
def test_every_strategy_stops_within_its_budget_and_an_open_loop_one_asks_its_size(name):
    kind, problem = problem_for(name, max_points=6)
    run = drive(lambda: kind(problem), problem)
    assert run.points <= problem.max_points and run.stopped in ("budget", "strategy")
    if not kind.closed_loop:  # a grid: every point known without results, as many as its size (when it knows)
        asked = list(iter(kind(problem).ask, None))
        assert asked[: len(run.asked)] == run.asked
        assert kind(problem).size in (None, len(asked))
        assert all(problem.admits(p) for p in asked)  # the grid leaves out what the constraints reject


@pytest.mark.parametrize("name", STRATEGIES)
def test_a_strategy_reads_the_pareto_objectives_only_if_it_is_multi_objective(name):
    """The same seed and f, with g minimised or maximised: a multi-objective strategy, once past its first
    random generation, asks other points (it reads g); any other asks the same points (it optimises the
    ranking's objective alone). Every result it is told has a value for each objective."""
    kind = search.strategy(name)
    budget = 80 if kind.multi_objective else 14  # four generations of nsga2's 20
    _, minimise = problem_for(name, max_points=budget, pareto=(("f", "min"), ("g", "min")))
    _, maximise = problem_for(name, max_points=budget, pareto=(("f", "min"), ("g", "max")))
    one, other = drive(lambda: kind(minimise), minimise), drive(lambda: kind(maximise), maximise)
    assert all(set(e.values) == {"f", "g"} for _, e in one.told if e.state == "ok")
    if kind.multi_objective:
        assert one.asked != other.asked, f"{name} asked the same points whether g is minimised or maximised"
    else:
        assert one.asked == other.asked, f"{name} asked other points when only a Pareto objective changed"
