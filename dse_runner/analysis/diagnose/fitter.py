"""The one fitter every diagnosis runs its fits through: fit problems for sets of hypotheses, their fits in
lockstep (each round one sweep into the store), and each candidate's held-out error.

Why one: every library fits the same way (the calibrated parameters freed beside a set's own, least
squares on the whole model's residuals, folds from validation.py), and differs only in what its
hypotheses' parameters are, what the fits minimise and how a held-out run is scored. A library gives
those three; a fix to the fitting then reaches every case.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

from ...sweeps.domain import Point
from ...sweeps.expand import key_of, wanted
from ...sweeps.fit import FitProblem, FitResult, Parameter, Residuals
from ...sweeps.fit_rounds import evaluate_points, fit_all, residuals_in
from ...sweeps.spec import Space
from . import explain
from .explain import Candidate
from .validation import Fold, Validation

MAX_ITERATIONS = 30  # Levenberg-Marquardt iterations a fit gets unless its library says otherwise

Messages = Callable[[str], None]


def label(ids: Sequence[str]) -> str:
    """A set of hypotheses as its fits are named: ``none`` for the empty set."""
    return "+".join(ids) or "none"


@dataclass
class Fitter:
    """What every fit of one diagnosis shares, and the fits themselves.

    ``parameters`` gives a hypothesis' own parameters by id; ``residuals`` is what the fits minimise (a
    vector objective's name, or ``{residual column: scale}``); ``score`` turns a held-out run's row of
    ``scored`` columns into its error (infinite for a run that failed); ``in_sample`` is a fit's error on
    what it saw, the only error when a record is too short to hold anything out."""

    space: Space
    client: Any
    base: tuple[Parameter, ...]  # the calibrated parameters every fit frees
    parameters: Callable[[str], Sequence[Parameter]]
    unfreed: Mapping[str, Any]  # what a fit leaves fixed unless it frees it
    validation: Validation
    residuals: str | Mapping[str, float]
    scored: list[str]
    score: Callable[[Mapping[str, Any] | None], float]
    say: Messages
    in_sample: Callable[[FitResult], float] = explain.fitted_rms
    iterations: int = MAX_ITERATIONS

    @property
    def scenarios(self) -> tuple[str, ...]:
        """What a fit on everything fits: a record's views are only for its folds."""
        return self.validation.fitted

    @property
    def folds(self) -> list[Fold]:
        return self.validation.folds

    def problem(
        self,
        name: str,
        ids: Sequence[str],
        on: Sequence[str],
        start: Mapping[str, float] = {},
        iterations: int | None = None,
    ) -> FitProblem:
        """The calibrated parameters and the hypotheses ``ids`` freed (from ``start`` where it says), fitted
        on the scenarios ``on``."""
        freed = tuple(
            replace(p, start=start.get(p.name, p.start))
            for p in (*self.base, *(p for h in ids for p in self.parameters(h)))
        )
        names = {p.name for p in freed}
        fixed = {k: v for k, v in self.unfreed.items() if k not in names}
        return FitProblem(name, freed, fixed, tuple(on), iterations or self.iterations)

    def full(self, ids: Sequence[str], start: Mapping[str, float] = {}) -> FitProblem:
        """The fit of a set on everything."""
        return self.problem(label(ids), ids, self.scenarios, start)

    def by_fold(self, ids: Sequence[str], start: Mapping[str, float] = {}) -> list[FitProblem]:
        """The fits of a set on each fold's fitting part, from ``start`` (its fit on everything)."""
        name = label(ids)
        return [self.problem(f"{name}/fold{k}", ids, fold.train, start) for k, fold in enumerate(self.folds)]

    def fit(self, problems: list[FitProblem], what: str = "fits") -> dict[str, FitResult]:
        """Every problem fitted, all in the same rounds; by label."""
        if not problems:
            return {}
        return fit_all(self.space, problems, self.client, self.residuals, round_report(self.say, what))

    def hold_out(self, candidates: Sequence[Candidate], results: Mapping[str, FitResult]) -> None:
        """Attach each candidate's fold fits and score every scenario (run or block) its fold's fit did not
        see, all in one sweep; with nothing held out, its error on what it saw."""
        if not self.folds:
            for c in candidates:
                c.held_out = {"fitted": self.in_sample(c.full)}
            return
        rows = self.rows(
            [
                (results[f"{c.label}/fold{k}"].point, fold.test)
                for c in candidates
                for k, fold in enumerate(self.folds)
            ]
        )
        for c in candidates:
            for k, fold in enumerate(self.folds):
                fit = results[f"{c.label}/fold{k}"]
                c.folds.append(fit)
                for scenario in fold.test:
                    c.held_out[scenario] = self.score(rows.get((key_of(fit.point), scenario)))

    def rows(
        self, requests: Sequence[tuple[Point, Sequence[str]]], columns: Sequence[str] | None = None
    ) -> dict[tuple[str, str], Mapping[str, Any]]:
        """The rows of points on their scenarios (``columns``: default the scored ones), in one sweep."""
        points, only = wanted(requests)
        rows, _ = evaluate_points(self.space, points, self.client, list(columns or self.scored), only)
        return rows

    def evaluate(self, points: list[Point], scenarios: Sequence[Sequence[str]] | None = None) -> Residuals:
        """The residuals of ``points`` on everything (or each on its ``scenarios``), as one sweep, as the
        fits read them (one vector objective, or scaled columns joined): a screen's probes and trials."""
        on = [self.scenarios if scenarios is None else s for s in (scenarios or [None] * len(points))]
        columns = [self.residuals] if isinstance(self.residuals, str) else list(self.residuals)
        return residuals_in(self.rows(list(zip(points, on)), columns), self.residuals)


def round_report(say: Messages, what: str = "fits") -> Callable[[int, int, int, int], None]:
    """The progress line of every round of a batch of fits."""

    def report(round_: int, active: int, points: int, simulations: int) -> None:
        say(f"{what}: round {round_}, {active} active, {points} points, {simulations} simulations")

    return report


def scored_ok(column: str) -> Callable[[Mapping[str, Any] | None], float]:
    """A held-out run's error as one objective's value, infinite for a run that failed or was never made."""

    def score(row: Mapping[str, Any] | None) -> float:
        return float(row[column]) if row and row["status"] == "ok" else math.inf

    return score
