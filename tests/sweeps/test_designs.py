"""Sensitivity designs (sweeps/strategies/designs.py) without a cluster: the budget buys whole blocks, a
larger budget extends the same design, repeats are asked once, constraints are honoured, and bad input
names its culprit. The contract every strategy keeps is tests/sweeps/test_every_strategy.py's; these
runs on the real cluster are tests/analysis/test_sensitivity.py's."""

from __future__ import annotations

import numpy as np
import pytest

from dse_runner.errors import DseError
from dse_runner.sweeps import search
from dse_runner.sweeps.domain import Dimension
from dse_runner.sweeps.search import Problem

X = Dimension("m.x", low=-1.0, high=1.0)
Y = Dimension("m.y", low=0.1, high=10.0, log=True)
Z = Dimension("m.z", low=0.0, high=4.0)
GRID = Dimension("m.g", low=0.0, high=1.0, step=0.5)


def problem(
    *dimensions: Dimension, max_points: int = 100, seed: int = 3, options=None, admits=None
) -> Problem:
    return Problem(
        label="designs",
        dimensions=dimensions,
        objective=("f", "min"),
        pareto=(),
        scenarios=("s",),
        vectors=(),
        max_points=max_points,
        seed=seed,
        batch=4,
        options=options or {},
        admits=admits or (lambda p: True),
        constrained=admits is not None,
    )


def asked(name: str, p: Problem) -> list[dict]:
    return list(iter(search.strategy(name)(p).ask, None))


@pytest.mark.parametrize(
    ("name", "options", "block"),
    [("sobol_indices", {}, 5), ("sobol_indices", {"second_order": True}, 8), ("morris", {}, 4)],
)
def test_the_budget_buys_whole_blocks_and_a_larger_one_extends_the_same_design(name, options, block):
    small = search.strategy(name)(problem(X, Y, Z, max_points=101, options=options))
    rows = len(small.design.units)
    assert small.design.block == block and rows % block == 0
    if name == "sobol_indices":  # continuous: every row a new point
        assert rows == (101 // block) * block
    else:  # Morris moves on a grid of 4 levels: 64 points in all, met again by more trajectories
        assert rows >= (101 // block) * block
    assert small.size == len(asked(name, problem(X, Y, Z, max_points=101, options=options))) <= 101
    large = search.strategy(name)(problem(X, Y, Z, max_points=400, options=options))
    assert np.array_equal(large.design.units[: len(small.design.units)], small.design.units)


def test_saltelli_blocks_cross_one_parameter_at_a_time():
    """Each block: A, then A with column j taken from B for each j, then B (SALib's layout, which the
    estimator reads back)."""
    design = search.strategy("sobol_indices")(problem(X, Y, Z, max_points=50)).design
    for first in range(0, len(design.units), design.block):
        a, b = design.units[first], design.units[first + design.block - 1]
        for j in range(3):
            crossed = design.units[first + 1 + j]
            assert crossed[j] == b[j] and np.array_equal(np.delete(crossed, j), np.delete(a, j))


def test_a_point_met_twice_is_asked_once_and_the_budget_counts_distinct_points():
    """On a 3 x 3 grid Morris' trajectories meet the same points again and again: the design grows until its
    distinct points fill the budget, or the grid has no more."""
    points = asked("morris", problem(GRID, Dimension("m.h", low=0.0, high=1.0, step=0.5), max_points=6))
    keys = [tuple(p.values()) for p in points]
    assert len(keys) == len(set(keys)) <= 6
    every = asked("morris", problem(GRID, Dimension("m.h", low=0.0, high=1.0, step=0.5), max_points=50))
    assert len(every) <= 9  # a 3 x 3 grid has 9 points; the design stops growing when nothing new comes


def test_a_design_that_cannot_spend_its_budget_says_how_many_points_it_runs_and_how_to_get_more():
    """Morris on 4 levels in 2-D has 16 distinct points, whatever the budget; on grids, the grids hold the
    points; a design that spends its budget says nothing."""
    morris = search.strategy("morris")(problem(X, Z, max_points=60))
    assert morris.size == 16
    assert morris.spending() == (
        "search: morris runs 16 distinct points of max_points 60: 4 levels over 2 "
        "parameters give at most 16 points; more levels (search: {levels: 8}) give more"
    )
    finer = search.strategy("morris")(problem(X, Z, max_points=60, options={"levels": 8}))
    assert finer.size > 50 and finer.spending() is None
    grids = search.strategy("sobol_indices")(
        problem(GRID, Dimension("m.h", low=0.0, high=1.0, step=0.5), max_points=60)
    )
    assert grids.size == 9 and "grids and choices hold 9 points" in grids.spending()
    assert search.strategy("sobol_indices")(problem(X, Y, Z, max_points=101)).spending() is None


def test_the_same_seed_asks_the_same_points_and_another_seed_others():
    assert asked("sobol_indices", problem(X, Y, seed=5)) == asked("sobol_indices", problem(X, Y, seed=5))
    assert asked("sobol_indices", problem(X, Y, seed=5)) != asked("sobol_indices", problem(X, Y, seed=6))


def test_points_the_constraints_refuse_are_not_asked():
    def admits(p):
        return p["m.x"] < 0.5

    points = asked("sobol_indices", problem(X, Y, max_points=40, admits=admits))
    assert points and all(p["m.x"] < 0.5 for p in points)


@pytest.mark.parametrize(
    ("name", "options", "message"),
    [
        (
            "sobol_indices",
            {},
            r"search: sobol_indices needs at least 5 points for 3 parameters .*max_points is 4",
        ),
        ("sobol_indices", {"second_order": True}, r"needs at least 8 points for 3 parameters"),
        ("morris", {}, r"search: morris needs at least 4 points for 3 parameters .*max_points is 3"),
    ],
)
def test_too_few_points_for_one_block_is_an_error_naming_the_budget(name, options, message):
    with pytest.raises(DseError, match=message):
        search.strategy(name)(
            problem(X, Y, Z, max_points=4 if name == "sobol_indices" else 3, options=options)
        )


def test_text_values_and_bad_options_are_errors_naming_them():
    mode = Dimension("m.mode", choices=(0.1, "off"))
    with pytest.raises(DseError, match=r"need numeric parameters; m\.mode lists text values"):
        search.strategy("sobol_indices")(problem(X, mode))
    with pytest.raises(DseError, match=r"search\.levels: .*multiple of 2 \(an option of Morris\)"):
        search.strategy("morris")(problem(X, options={"levels": 5}))
    with pytest.raises(DseError, match=r"search\.second_ordr: extra inputs are not permitted"):
        search.strategy("sobol_indices")(problem(X, options={"second_ordr": True}))


def test_fast_buys_one_curve_per_parameter_each_running_its_parameter_fastest():
    """eFAST: D curves of max_points // D rows (SALib's layout: curve i runs parameter i at the highest
    frequency); the same seed gives the same curves, and too small a budget for N > 4 M^2 names it."""
    design = search.strategy("fast")(problem(X, Y, Z, max_points=400)).design
    assert (design.method, design.block, design.blocks, design.harmonics) == ("fast", 133, 3, 4)
    assert len(asked("fast", problem(X, Y, Z, max_points=400))) <= 399
    for i in range(3):  # the parameter at the highest frequency crosses the cube's middle most often
        curve = design.units[i * design.block : (i + 1) * design.block]
        crossings = np.count_nonzero(np.diff(np.sign(curve - 0.5), axis=0), axis=0)
        assert crossings.argmax() == i, (i, crossings)
    assert asked("fast", problem(X, Y, seed=5, max_points=200)) == asked(
        "fast", problem(X, Y, seed=5, max_points=200)
    )
    with pytest.raises(
        DseError, match=r"search: fast needs at least 195 points for 3 parameters .*max_points is 194"
    ):
        search.strategy("fast")(problem(X, Y, Z, max_points=194))
    assert (
        search.strategy("fast")(problem(X, Y, Z, max_points=15, options={"harmonics": 1})).design.block == 5
    )


@pytest.mark.parametrize(
    ("name", "options"),
    [
        ("sobol_indices", {}),
        ("sobol_indices", {"second_order": True}),
        ("morris", {}),
        ("morris", {"levels": 6}),
    ],
)
def test_a_design_over_intervals_is_computed_on_whole_columns_to_the_same_points(name, options):
    """The column-wise path (no Python object per row, for designs of a million points) asks the very points,
    in the very order, that mapping each row and keeping its first occurrence gives, with the same budget."""
    from dse_runner.sweeps.domain import from_units
    from dse_runner.sweeps.strategies import designs

    x, z, w = (
        Dimension("m.x", low=-1, high=1),
        Dimension("m.z", low=0.0, high=4.0),
        Dimension("m.w", low=2, high=3),
    )
    p = problem(x, z, w, max_points=203, options=options)
    fast = search.strategy(name)(p)
    assert isinstance(designs._budgeted_intervals(fast.design, p)[1], np.ndarray)  # the fast path served
    by_row, seen = [], set()
    for row in fast.design.units:
        point = from_units([x, z, w], row)
        if tuple(point.values()) not in seen:
            seen.add(tuple(point.values()))
            by_row.append(point)
    assert list(iter(fast.ask, None)) == by_row and fast.size == len(by_row) <= 203
    assert designs._budgeted(fast.design, p) == (fast.design.blocks, by_row)  # the row-by-row path agrees


def test_a_design_is_drawn_when_first_needed_and_once_for_the_same_problem():
    """A spec's check builds the strategy (a million-row design takes seconds to draw): building it draws
    nothing; the strategies a sweep builds to count, to warn and to ask share one drawing, each asking from
    the start; another seed is another design."""
    from dse_runner.sweeps.strategies import designs

    p = problem(X, Z, max_points=160, seed=11)
    designs._DRAWN.clear()
    first = search.strategy("sobol_indices")(p)
    assert not designs._DRAWN  # built, not drawn
    second = search.strategy("sobol_indices")(p)
    assert first.design is second.design and len(designs._DRAWN) == 1
    assert list(iter(first.ask, None)) == list(iter(second.ask, None)) == asked("sobol_indices", p)
    other = search.strategy("sobol_indices")(problem(X, Z, max_points=160, seed=12))
    assert other.design is not first.design and not np.array_equal(other.design.units, first.design.units)


@pytest.mark.parametrize("options", [{}, {"second_order": True}])
def test_a_saltelli_design_over_intervals_streams_the_whole_draws_points_without_holding_them(
    monkeypatch, options
):
    """A million-row study must not cost the client the design: over plain intervals the points are drawn a
    few blocks at a time (here 7, so parts start at blocks that are no power of two) and are the very points
    of the whole draw the sensitivity command reads back, in order; counting and asking leave no design
    drawn."""
    from dse_runner.sweeps.domain import from_units
    from dse_runner.sweeps.strategies import designs

    monkeypatch.setattr(designs, "STREAM_BLOCKS", 7)
    p = problem(X, Z, Dimension("m.w", low=2, high=3), max_points=307, seed=5, options=options)
    designs._DRAWN.clear()
    streamed = search.strategy("sobol_indices")(p)
    assert streamed.streams()
    size, points = streamed.size, list(iter(streamed.ask, None))
    assert not designs._DRAWN  # counted and asked, never drawn whole
    whole = search.strategy("sobol_indices")(p).design  # as the sensitivity command draws it
    assert len(whole.units) == (307 // whole.block) * whole.block and whole.blocks > 7
    assert points == [from_units(list(p.dimensions), row) for row in whole.units] and size == len(points)


def test_a_design_streams_only_where_no_two_blocks_can_share_a_point():
    """Grids, log axes, a single parameter (its crossed row is its B row) and constraints keep the whole
    draw and its global dedup."""

    def streams(*dimensions, admits=None):
        return search.strategy("sobol_indices")(problem(*dimensions, max_points=60, admits=admits)).streams()

    assert streams(X, Z) and not streams(X) and not streams(X, GRID) and not streams(X, Y)
    assert not streams(X, Z, admits=lambda p: True)
    assert not search.strategy("morris")(problem(X, Z, max_points=60)).streams()


@pytest.mark.parametrize("second_order", [False, True])
@pytest.mark.parametrize(("n", "skip"), [(1, 0), (37, 0), (64, 64), (19, 45)])
def test_saltelli_rows_are_salib_s_to_the_bit(second_order, n, skip):
    """The design's rows are SALib.sample.sobol's (the estimator reads them back in its order), also a part
    drawn from any base row on."""
    import warnings

    from SALib.sample import sobol

    from dse_runner.sweeps.strategies import designs

    p = problem(X, Y, Z, max_points=10_000, seed=9, options={"second_order": second_order})
    ours = search.strategy("sobol_indices")(p).draw_part(p, n, skip).units
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        theirs = sobol.sample(
            designs.salib_problem(p.dimensions),
            n,
            calc_second_order=second_order,
            scramble=True,
            seed=9,
            skip_values=skip,
        )
    assert ours.shape == theirs.shape and np.array_equal(ours, theirs)
