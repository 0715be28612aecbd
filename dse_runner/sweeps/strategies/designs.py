"""Sampling designs for global sensitivity analysis: Saltelli's (``sobol_indices``), Morris' (``morris``) and
the extended Fourier amplitude sensitivity test's (``fast``).

Unlike a search, a sensitivity study needs its points in a fixed pattern that the estimator
reads back: Saltelli's base rows each followed by one cross-sampled row per parameter, or
Morris trajectories that move one parameter a level at a time, or eFAST's search curves, one per
parameter, each running that parameter at the highest frequency. SALib draws them in the unit
cube; the points are those rows mapped to values (domain.py), asked up front like a grid's
(``closed_loop = False``), so they run in large chunks, resume by task id and land in the
same store as any sweep. analysis/sensitivity.py draws the same :class:`Design` again from the
saved spec and reads each row's result back by its point.

The budget ``max_points`` buys whole blocks (a Saltelli base row's ``D + 2`` rows, or
``2D + 2`` with second order; a Morris trajectory's ``D + 1``): as many as fit that many
distinct points, ``max_points // block`` over continuous parameters. eFAST's curves do not extend
(their frequencies depend on their length): it buys D curves of ``max_points // D`` rows. A point met twice
(discrete parameters can map two rows to one point) is asked once; a point the constraints
reject is not asked, and its block is left out of the indices.

A Saltelli design over plain intervals without constraints is never held by the sweep: its points are
drawn a part at a time as they are asked (the Sobol' sequence fast-forwarded), so a million-row study
costs the client what a thousand-row one does.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any, ClassVar

import numpy as np
import pandas as pd
from pydantic import Field, PositiveInt

from ...errors import DseError
from ..domain import Dimension, Point, from_units
from ..search import Options, Problem, Strategy


@dataclass(frozen=True)
class Design:
    """A sensitivity method's sample in the unit cube, in the order its estimator reads it."""

    method: str  # "sobol" | "morris" | "fast": which SALib estimator reads it
    units: np.ndarray  # rows x dimensions, in [0, 1]
    block: int  # consecutive rows the estimator needs together: one base row's, one trajectory, or one curve
    second_order: bool = False
    levels: int = 0  # Morris' grid levels
    harmonics: int = 0  # eFAST's interference parameter M

    @property
    def blocks(self) -> int:
        return len(self.units) // self.block

    def points(self, dimensions: tuple[Dimension, ...]) -> list[Point]:
        """Every row as a point (repeats included), in the design's order."""
        return [from_units(list(dimensions), row) for row in self.units]


def plain_intervals(dimensions: tuple[Dimension, ...]) -> bool:
    """Whether every parameter is an interval without log, integer, step or choices: a design's rows then
    never meet the same point twice."""
    return bool(dimensions) and all(
        d.choices is None and d.step is None and not d.integer and not d.log and d.low is not None
        for d in dimensions
    )


def interval_values(dimensions: tuple[Dimension, ...], units: np.ndarray) -> np.ndarray | None:
    """``units`` mapped to values on whole columns where every parameter is a plain interval (no log, integer,
    step or choices): the very numbers ``Dimension.from_unit`` gives row by row (the same IEEE operations,
    low + u * (high - low)), without a Python object per row. None for any other design."""
    if not plain_intervals(dimensions):
        return None
    low = np.array([float(d.low) for d in dimensions])
    high = np.array([float(d.high) for d in dimensions])
    return low + np.clip(units, 0.0, 1.0) * (high - low)


def salib_problem(dimensions: tuple[Dimension, ...]) -> dict[str, Any]:
    """SALib's problem: every parameter on [0, 1]; domain.py maps units to values (log, grids, choices)."""
    return {
        "num_vars": len(dimensions),
        "names": [d.name for d in dimensions],
        "bounds": [[0.0, 1.0]] * len(dimensions),
    }


def numeric(dimensions: tuple[Dimension, ...]) -> None:
    """Indices move each parameter along its axis: text choices have no order to move along."""
    text = [
        d.name
        for d in dimensions
        if d.choices is not None and any(isinstance(v, (str, bool)) for v in d.choices)
    ]
    if text:
        raise DseError(
            f"search: sensitivity designs need numeric parameters; {', '.join(text)} "
            "lists text values (a design moves each parameter along a numeric axis)"
        )


class SensitivityDesign(Strategy):
    """A fixed design asked up front; subclasses say how many rows a block has and how SALib draws them."""

    closed_loop = False
    method: ClassVar[str]
    label: ClassVar[str]  # its name under search.strategy, for messages

    def __init__(self, problem: Problem):
        """Checks what can be checked without drawing; the design is drawn when first asked for
        (a spec's check builds the strategy, and a million-row design takes seconds), once
        per process for the same problem."""
        super().__init__(problem)
        numeric(problem.dimensions)
        self.check_budget(problem)
        self._asking: Any = None  # the points' iterator, from the first ask
        self._own: tuple[Design, list[Point] | np.ndarray | None] | None = (
            None  # a constrained design, drawn for this one
        )

    @property
    def design(self) -> Design:
        return _fitted(self)[0]

    @property
    def size(self) -> int:  # type: ignore[override]  # known once drawn, and drawn when asked
        if self.streams():
            return _streamed_size(self)
        return len(_fitted(self)[1])

    def streams(self) -> bool:
        """Whether the points are drawn a part at a time as they are asked, never held whole:
        the client's memory then stays flat in the design's size. A design that can start
        drawing at any block says when."""
        return False

    def identity(self) -> tuple | None:
        """What fixes the design, to reuse one drawn already; None when constraints judge its points (a
        function of the spec, not told apart here)."""
        problem = self.problem
        if problem.constrained:
            return None
        return (
            type(self),
            self.options.model_dump_json(),
            problem.dimensions,
            problem.max_points,
            problem.seed,
        )

    def check_budget(self, problem: Problem) -> None:
        """The budget buys at least one block."""
        block = self.block_of(len(problem.dimensions), self.options)
        if problem.max_points < block:
            raise DseError(
                f"search: {self.label} needs at least {block} points for {len(problem.dimensions)} "
                f"parameters (one block of {self.rows_in_words()}); max_points is {problem.max_points}"
            )

    def fit(self, problem: Problem) -> tuple[Design, list[Point] | np.ndarray | None]:
        """The longest prefix of whole blocks whose distinct admitted points fit the budget. Repeats are
        free (a point is simulated once), so a design over grids or choices is drawn again twice as long
        while the budget has room: both SALib designs extend as prefixes for the same seed."""
        block = self.block_of(len(problem.dimensions), self.options)
        n, found = problem.max_points // block, -1
        if self.streams():
            return self.draw(problem, n), None  # its points are asked a part at a time: parts()
        while True:
            design = self.draw(problem, n)
            blocks, points = _budgeted_intervals(design, problem) or _budgeted(design, problem)
            if blocks < design.blocks or len(points) == found or n >= problem.max_points:
                break  # the budget is spent, or longer adds nothing, or there is a block per point of budget
            if plain_intervals(problem.dimensions) and problem.max_points - len(points) < block:
                break  # rows that never repeat: no further block fits (drawing it would cost as much again)
            n, found = 2 * n, len(points)
        units = design.units[: blocks * design.block]
        return replace(design, units=units), points

    @classmethod
    def block_of(cls, dimensions: int, options: Any) -> int:
        raise NotImplementedError

    @classmethod
    def rows_in_words(cls) -> str:
        raise NotImplementedError

    def draw(self, problem: Problem, n: int) -> Design:
        """``n`` blocks of the design."""
        raise NotImplementedError

    def draw_part(self, problem: Problem, n: int, skip: int) -> Design:
        """``n`` blocks of the design from its block ``skip`` on, the very rows of a whole draw: what a design
        that :meth:`streams` draws a part at a time."""
        raise NotImplementedError

    def parts(self) -> Iterator[np.ndarray]:
        """For a design that :meth:`streams`: its points, :data:`STREAM_BLOCKS` blocks at a time, each part's
        repeats asked once. The same blocks :meth:`fit` keeps, and so the rows the estimator reads back."""
        problem = self.problem
        blocks = problem.max_points // self.block_of(len(problem.dimensions), self.options)
        for skip in range(0, blocks, STREAM_BLOCKS):
            part = self.draw_part(problem, min(STREAM_BLOCKS, blocks - skip), skip)
            values = interval_values(problem.dimensions, part.units)
            yield values[~pd.DataFrame(values).duplicated(keep="first").to_numpy()]

    def ask(self) -> Point | None:
        if self._asking is None:
            names = [d.name for d in self.problem.dimensions]
            parts = self.parts() if self.streams() else iter([_fitted(self)[1]])
            self._asking = (point for part in parts for point in _asked(part, names))
        return next(self._asking, None)

    def spending(self) -> str | None:
        """Said when a whole block of the budget is left: the design's grid (Morris' levels, the grids and
        choices of the parameters) holds fewer distinct points than the budget buys rows, or the
        constraints reject some."""
        left = self.problem.max_points - self.size
        if left < self.block_of(len(self.problem.dimensions), self.options):
            return None
        return (
            f"search: {self.label} runs {self.size} distinct points of max_points "
            f"{self.problem.max_points}: {self.more()}"
        )

    def more(self) -> str:
        """How to get more distinct points out of the design."""
        finite = distinct_points(self.problem.dimensions)
        if finite is not None:
            return (
                f"the parameters' grids and choices hold {finite} points; finer grids or intervals give more"
            )
        return "the constraints leave few points; widen them, or lower max_points"


_DRAWN: dict[
    tuple, tuple[Design, list[Point] | np.ndarray | None]
] = {}  # the last designs drawn, by identity()
DRAWN_KEPT = 2
STREAM_BLOCKS = (
    8192  # blocks drawn at a time by a design that streams: about 1 MB of rows for a few parameters
)
_COUNTED: dict[tuple, int] = {}  # the points of designs that stream, by identity(): counting draws them all


def _streamed_size(design: SensitivityDesign) -> int:
    """How many points a design that streams asks: its parts drawn and counted once per process, none kept."""
    key = design.identity()
    if key not in _COUNTED:
        _COUNTED[key] = sum(len(part) for part in design.parts())
    return _COUNTED[key]


def _fitted(design: SensitivityDesign) -> tuple[Design, list[Point] | np.ndarray | None]:
    """The strategy's design and its points to ask, drawn once per process for the same identity: a sweep
    builds its strategy to check the spec, to count its tasks and to ask its points, and the sensitivity
    command to read the rows back."""
    key = design.identity()
    if key is None:
        if design._own is None:
            design._own = design.fit(design.problem)
        return design._own
    if key not in _DRAWN:
        while len(_DRAWN) >= DRAWN_KEPT:
            _DRAWN.pop(next(iter(_DRAWN)))
        _DRAWN[key] = design.fit(design.problem)
    return _DRAWN[key]


def distinct_points(dimensions: tuple[Dimension, ...]) -> int | None:
    """How many points the parameters' grids and choices hold, or None when one is an interval."""
    grids = [d.grid() for d in dimensions]
    return None if any(g is None for g in grids) else math.prod(len(set(g)) for g in grids)


def _asked(points: list[Point] | np.ndarray, names: list[str]):
    """The points to ask, one at a time: a matrix of values becomes a point only when asked (a million
    points held as dicts would cost the client half a gigabyte)."""
    if isinstance(points, np.ndarray):
        return (dict(zip(names, row.tolist())) for row in points)  # a row's list made when it is asked
    return iter(points)


def _budgeted_intervals(design: Design, problem: Problem) -> tuple[int, np.ndarray] | None:
    """:func:`_budgeted` on whole columns, for a design over plain intervals without constraints: the same
    blocks and the same points in the same order (each distinct row where it first occurs), as a matrix.
    None where it does not apply."""
    if problem.constrained:
        return None
    values = interval_values(problem.dimensions, design.units)
    if values is None or not len(values):
        return None
    is_new = ~pd.DataFrame(values).duplicated(keep="first").to_numpy()  # hashed: a sort of rows costs seconds
    ends = np.arange(1, design.blocks + 1) * design.block
    distinct = np.cumsum(is_new)[ends - 1]  # distinct points in the first 1, 2, ... blocks
    blocks = int(np.searchsorted(distinct, problem.max_points, side="right"))
    used = blocks * design.block
    return blocks, values[:used][is_new[:used]]


def _budgeted(design: Design, problem: Problem) -> tuple[int, list[Point]]:
    """How many leading blocks fit ``max_points`` distinct admitted points, and those points in order."""
    seen: dict[tuple, Point] = {}
    rows = design.points(problem.dimensions)
    for b in range(design.blocks):
        new: dict[tuple, Point] = {}
        for point in rows[b * design.block : (b + 1) * design.block]:
            key = tuple(point.values())
            if key not in seen and key not in new and problem.admits(point):
                new[key] = point
        if len(seen) + len(new) > problem.max_points:
            return b, list(seen.values())
        seen.update(new)
    return design.blocks, list(seen.values())


def saltelli_rows(base: np.ndarray, second_order: bool) -> np.ndarray:
    """Saltelli's rows of Sobol' base rows (A | B, 2D columns) in SALib.sample.sobol's order: for each base
    row A, A with its column j taken from B for each j, with second order B with its column j taken from
    A, then B. Built on whole columns where SALib loops over the rows in Python (2 s at a million rows,
    drawn by both submit and the sensitivity command); test_designs.py checks the two agree to the bit."""
    d = base.shape[1] // 2
    a, b, column = base[:, :d], base[:, d:], np.arange(d)
    crossed = [np.where(column == j, b, a) for j in range(d)]
    if second_order:
        crossed += [np.where(column == j, a, b) for j in range(d)]
    return np.stack([a, *crossed, b], axis=1).reshape(-1, d)


class SobolOptions(Options):
    second_order: bool = False  # also S2: 2D + 2 rows per base row instead of D + 2


class SobolIndices(SensitivityDesign):
    """Saltelli's extension of a scrambled Sobol' sequence (SALib.sample.sobol), for first-, total- and
    optionally second-order Sobol' indices. Base samples that are powers of two balance best."""

    Options = SobolOptions
    method, label = "sobol", "sobol_indices"

    @classmethod
    def block_of(cls, dimensions: int, options: SobolOptions) -> int:
        return 2 * dimensions + 2 if options.second_order else dimensions + 2

    @classmethod
    def rows_in_words(cls) -> str:
        return "D + 2 rows, 2D + 2 with second_order"

    def streams(self) -> bool:
        """Without constraints, over two or more plain intervals: rows repeat inside a block (a
        cross-sampled row that draws its base row's value), and rows of two blocks meet only if two
        coordinates of the Sobol' sequence coincide by chance (odds near blocks^2 * 2^-60; one
        coordinate never repeats), which at worst simulates a point twice. So every block is kept, and
        its points are known a part at a time."""
        problem = self.problem
        return (
            not problem.constrained and len(problem.dimensions) >= 2 and plain_intervals(problem.dimensions)
        )

    def draw(self, problem: Problem, n: int) -> Design:
        return self.draw_part(problem, n, 0)

    def draw_part(self, problem: Problem, n: int, skip: int) -> Design:
        """SALib.sample.sobol's rows from base row ``skip`` on (its ``skip_values``: the scrambled Sobol'
        sequence fast-forwarded), the rows of the whole draw's blocks ``skip`` to ``skip + n``."""
        from scipy.stats import qmc  # on first use: scipy.stats costs every command about a second to import

        engine = qmc.Sobol(2 * len(problem.dimensions), scramble=True, seed=problem.seed)
        if skip:  # (scipy refuses to fast-forward by nothing)
            engine.fast_forward(skip)
        with (
            warnings.catch_warnings()
        ):  # balance is best at powers of two; any other N or skip still estimates
            warnings.simplefilter("ignore", UserWarning)
            units = saltelli_rows(engine.random(n), self.options.second_order)
        return Design(
            "sobol",
            units,
            self.block_of(len(problem.dimensions), self.options),
            second_order=self.options.second_order,
        )


class MorrisOptions(Options):
    levels: PositiveInt = Field(
        4, ge=2, multiple_of=2
    )  # grid levels of each parameter; even, as Morris' design needs


class Morris(SensitivityDesign):
    """Morris' elementary-effects screening (SALib.sample.morris): trajectories of D + 1 points, each
    moving one parameter by a fixed step on a grid of ``levels``. Cheap: a few tens of trajectories rank
    the parameters by mu* and tell non-linearity or interaction by sigma."""

    Options = MorrisOptions
    method, label = "morris", "morris"

    @classmethod
    def block_of(cls, dimensions: int, options: MorrisOptions) -> int:
        return dimensions + 1

    @classmethod
    def rows_in_words(cls) -> str:
        return "a trajectory of D + 1 rows"

    def draw(self, problem: Problem, n: int) -> Design:
        from SALib.sample import morris

        units = morris.sample(
            salib_problem(problem.dimensions), n, num_levels=self.options.levels, seed=problem.seed
        )
        return Design(
            "morris", units, self.block_of(len(problem.dimensions), self.options), levels=self.options.levels
        )

    def more(self) -> str:
        """Morris moves on a grid of ``levels`` per parameter, which holds levels^D points at most."""
        levels, d = self.options.levels, len(self.problem.dimensions)
        return (
            f"{levels} levels over {d} parameters give at most {levels**d} points; more levels "
            f"(search: {{levels: {2 * levels}}}) give more"
        )


class FastOptions(Options):
    harmonics: PositiveInt = (
        4  # M, the Fourier harmonics summed per frequency (SALib's default); curves need > 4 M^2 rows
    )


class Fast(SensitivityDesign):
    """The extended Fourier amplitude sensitivity test (Saltelli, Tarantola and Chan 1999;
    SALib.sample.fast_sampler): one search curve per parameter, that parameter oscillating at the
    highest frequency and the others at low ones, for first-order and total indices at D curves of N
    rows. A curve's frequencies depend on N, so a longer design is another design: the budget buys N =
    max_points // D rows per curve, drawn once."""

    Options = FastOptions
    method, label = "fast", "fast"

    @classmethod
    def block_of(cls, dimensions: int, options: FastOptions) -> int:
        """The shortest curve SALib accepts: N > 4 M^2."""
        return 4 * options.harmonics**2 + 1

    @classmethod
    def rows_in_words(cls) -> str:
        return "a curve of more than 4 M^2 rows (M = harmonics) per parameter"

    def check_budget(self, problem: Problem) -> None:
        """The budget buys a curve per parameter."""
        dimensions = len(problem.dimensions)
        shortest = self.block_of(dimensions, self.options)
        if problem.max_points < shortest * dimensions:
            raise DseError(
                f"search: fast needs at least {shortest * dimensions} points for {dimensions} parameters "
                f"({self.rows_in_words()}: {shortest} rows at harmonics {self.options.harmonics}); "
                f"max_points is {problem.max_points}"
            )

    def fit(self, problem: Problem) -> tuple[Design, list[Point]]:
        """D curves of ``max_points // D`` rows; the design's distinct admitted points, asked once each."""
        design = self.draw(problem, problem.max_points // len(problem.dimensions))
        seen: dict[tuple, Point] = {}
        for point in design.points(problem.dimensions):
            key = tuple(point.values())
            if key not in seen and problem.admits(point):
                seen[key] = point
        return design, list(seen.values())

    def draw(self, problem: Problem, n: int) -> Design:
        """``n`` rows per curve."""
        from SALib.sample import fast_sampler

        units = fast_sampler.sample(
            salib_problem(problem.dimensions), n, M=self.options.harmonics, seed=problem.seed
        )
        return Design("fast", units, n, harmonics=self.options.harmonics)
