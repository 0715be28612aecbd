"""Space-filling samples that need no results: random, Sobol and Latin hypercube (scipy.stats.qmc).

Each draws rows of the unit cube and maps them to points (domain.py). A point
the constraints reject is skipped and the next row drawn, so the budget goes
to feasible points only.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator

import numpy as np

from ..domain import Point, from_units
from ..search import Problem, Strategy

MAX_REJECTED = 10_000  # rows in a row the constraints reject before the search gives up


class UnitCubeSampling(Strategy):
    """A stream of unit-cube rows made points; subclasses say how rows are drawn."""

    def __init__(self, problem: Problem):
        super().__init__(problem)
        self._rows = self.rows(len(problem.dimensions), problem.seed, problem.max_points)

    def rows(self, dimensions: int, seed: int, count: int) -> Iterator[np.ndarray]:
        raise NotImplementedError

    def ask(self) -> Point | None:
        for _ in range(MAX_REJECTED):
            point = from_units(list(self.problem.dimensions), next(self._rows))
            if self.problem.admits(point):
                return point
        return None  # the constraints leave (almost) nothing: the search ends with what it has


class RandomSampling(UnitCubeSampling):
    """Independent uniform draws."""

    def rows(self, dimensions: int, seed: int, count: int) -> Iterator[np.ndarray]:
        generator = np.random.default_rng(seed)
        while True:
            yield generator.random(dimensions)


class Sobol(UnitCubeSampling):
    """A scrambled Sobol' sequence: the first n points of a longer run are the same n points, so a
    larger budget extends the sample."""

    def rows(self, dimensions: int, seed: int, count: int) -> Iterator[np.ndarray]:
        from scipy.stats import qmc  # on first use: scipy.stats costs every command about a second to import

        engine = qmc.Sobol(dimensions, scramble=True, seed=seed)
        while True:
            with (
                warnings.catch_warnings()
            ):  # balance is best at powers of two; any prefix is still low-discrepancy
                warnings.simplefilter("ignore", UserWarning)
                yield from engine.random(64)


class LatinHypercube(UnitCubeSampling):
    """A Latin hypercube of ``max_points`` rows (each parameter's range cut into that many strata, one
    point in each); rows beyond it come from further hypercubes of the same size."""

    def rows(self, dimensions: int, seed: int, count: int) -> Iterator[np.ndarray]:
        from scipy.stats import qmc

        engine = qmc.LatinHypercube(dimensions, seed=seed)
        while True:
            yield from engine.random(count)
