"""Calibration against recordings by least squares: fit.py's Levenberg-Marquardt as a strategy.

It minimises the sum of squares of a vector objective, one residual per
recorded sample (``fix_residuals`` for field data, or
``{signal, recorded, metric: residuals}`` for any recording), over every
scenario. Each iteration asks for a candidate and one forward-difference
perturbation per parameter, which run in parallel; the next iteration waits
for all of them. It stops when a step gains less than ``tolerance`` of the
sum of squares, so it may use fewer points than the budget.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from pydantic import Field, PositiveFloat, PositiveInt

from ...errors import DseError, did_you_mean
from ..domain import Point
from ..expand import key_of
from ..fit import FitProblem, LevenbergMarquardt, Parameter
from ..search import Evaluation, Options, Problem, Strategy


class LeastSquaresOptions(Options):
    residuals: str | None = None  # the vector objective; default: the space's first
    start: dict[str, float] = Field(default_factory=dict)  # default: the middle of each interval
    relative_step: PositiveFloat = Field(0.01, le=0.5)  # finite-difference step, as a fraction of the range
    max_iterations: PositiveInt = 15
    tolerance: PositiveFloat = 1e-4  # stop when a step gains less than this fraction of the sum of squares


class LeastSquares(Strategy):
    Options = LeastSquaresOptions

    def __init__(self, problem: Problem):
        super().__init__(problem)
        o: LeastSquaresOptions = self.options
        self.residuals = o.residuals or (problem.vectors[0] if problem.vectors else None)
        if self.residuals is None or self.residuals not in problem.vectors:
            raise DseError(
                f"search: least_squares fits a vector objective (one residual per recorded sample), e.g. "
                f"{{signal: ..., recorded: ..., metric: residuals}}; "
                f"the space has {', '.join(problem.vectors) or 'none'}"
            )
        discrete = [d.name for d in problem.dimensions if d.choices is not None]
        if discrete:
            raise DseError(
                f"search: least_squares needs numeric ranges; {', '.join(discrete)} is a list of choices"
            )
        stepped = [d.name for d in problem.dimensions if d.integer or d.step is not None]
        if stepped:  # its steps and finite differences move each parameter by fractions of its range
            raise DseError(
                f"search: least_squares moves every parameter continuously; {', '.join(stepped)} takes "
                "only whole numbers or a grid's steps: give it an interval {low, high}"
            )
        names = [d.name for d in problem.dimensions]
        unknown = sorted(set(o.start) - set(names))
        if unknown:
            raise DseError(
                f"search.start: {', '.join(unknown)} is not a swept parameter"
                f"{did_you_mean(unknown[0], names)}"
            )
        parameters = tuple(
            Parameter(
                d.name,
                o.start.get(d.name, (d.low + d.high) / 2),
                d.low,
                d.high,
                o.relative_step * (d.high - d.low),
            )
            for d in problem.dimensions
        )
        self.solver = LevenbergMarquardt(
            FitProblem(problem.label, parameters, {}, problem.scenarios, o.max_iterations, o.tolerance)
        )
        self._round()

    def _round(self) -> None:
        self.asked = deque(self.solver.ask())
        self.results: dict[tuple, Evaluation] = {}
        self.expected = len(self.asked)

    def ask(self) -> Point | None:
        return self.asked.popleft() if self.asked else None

    def tell(self, point: Point, evaluation: Evaluation) -> None:
        self.results[key_of(point)] = evaluation
        if len(self.results) < self.expected or self.asked:
            return
        results = self.results

        def residuals(p: Point, scenario: str) -> np.ndarray | None:
            found = results.get(key_of(p))
            if found is None or found.state != "ok":
                return None
            return np.asarray(found.scores[scenario][self.residuals], dtype=float)

        self.solver.tell(residuals)
        if self.solver.error is not None:
            raise DseError(
                f"search: least_squares cannot start: {self.solver.error} (give search.start a point "
                "that simulates)"
            )
        self._round()
