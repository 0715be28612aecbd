"""The chain of fits behind a diagnosis: every fit and evaluation a sweep of the effects multi-model, in
lockstep, into the store."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from ...analysis.diagnose.explain import Candidate
from ...analysis.diagnose.validation import Validation
from ...sweeps.domain import Point
from ...sweeps.expand import key_of, wanted
from ...sweeps.fit import FitProblem, FitResult, Parameter, Residuals
from ...sweeps.fit_rounds import evaluate_points, fit_all, residuals_in
from ...sweeps.spec import Space
from .hypotheses import hypothesis
from .outcome import DiagnosisSettings

RESIDUALS = (
    "fix_residuals"  # the field-data case's vector objective (cases/fielddata.py): offsets at every fix
)
DiagnosisMessages = Callable[[str], None]  # one line per step, for a person watching (the CLI: stderr)


def _effect_parameters(ids: tuple[str, ...], vehicle: str, start: dict[str, float]) -> tuple[Parameter, ...]:
    return tuple(
        Parameter(
            f"{vehicle}.{p.variable}", start.get(f"{vehicle}.{p.variable}", 0.0), p.lower, p.upper, p.step
        )
        for hid in ids
        for p in hypothesis(hid).parameters
    )


class Chain:
    """The state of one diagnosis between its steps."""

    def __init__(
        self,
        space: Space,
        vehicle: str,
        base: tuple[Parameter, ...],
        client,
        settings: DiagnosisSettings,
        progress: DiagnosisMessages,
        validation: Validation,
    ):
        self.space, self.vehicle, self.base, self.client = space, vehicle, base, client
        self.settings, self.say = settings, progress
        self.fixed = {name: values[0] for name, values in space.parameters.items()}
        self.validation = validation  # the engine's: folds of runs, or time blocks of one run
        self.folds = validation.folds
        self.all = validation.fitted

    def problem(
        self, label: str, ids: tuple[str, ...], start: dict[str, float], scenarios: tuple[str, ...]
    ) -> FitProblem:
        base = tuple(
            Parameter(p.name, start.get(p.name, p.start), p.lower, p.upper, p.step) for p in self.base
        )
        params = base + _effect_parameters(ids, self.vehicle, start)
        names = {p.name for p in params}
        fixed = {k: v for k, v in self.fixed.items() if k not in names}
        return FitProblem(label, params, fixed, scenarios, self.settings.max_iterations)

    def full(self, ids: tuple[str, ...], start: dict[str, float]) -> FitProblem:
        """The fit of a set on every run."""
        return self.problem("+".join(ids) or "none", ids, start, self.all)

    def by_fold(self, candidate: Candidate) -> list[FitProblem]:
        """The fits of a set on each fold's fitting part, each from the set's fit on every run."""
        return [
            self.problem(f"{candidate.label}/fold{k}", candidate.ids, candidate.full.values, fold.train)
            for k, fold in enumerate(self.folds)
        ]

    def fit(self, problems: list[FitProblem], what: str) -> dict[str, FitResult]:
        """Every problem in one lockstep batch: each round one sweep."""

        def report(round_: int, active: int, points: int, simulations: int) -> None:
            self.say(f"{what}: round {round_}, {active} fits, {points} points, {simulations} simulations")

        return fit_all(self.space, problems, self.client, RESIDUALS, report) if problems else {}

    def score(self, candidates: list[Candidate], fits: dict[str, FitResult]) -> None:
        """Attach each candidate's fold fits and predict every run (or block) it held out with the fit that
        did not see it, all in one sweep."""
        points, only = wanted(
            (fits[f"{c.label}/fold{k}"].point, fold.test)
            for c in candidates
            for k, fold in enumerate(self.folds)
        )
        rows, _ = evaluate_points(self.space, points, self.client, ["cross_track_error"], only)
        for c in candidates:
            for k, fold in enumerate(self.folds):
                fit = fits[f"{c.label}/fold{k}"]
                c.folds.append(fit)
                for scenario in fold.test:
                    row = rows.get((key_of(fit.point), scenario))
                    c.held_out[scenario] = (
                        float(row["cross_track_error"]) if row and row["status"] == "ok" else math.inf
                    )

    def evaluate(self, points: list[Point], scenarios: Sequence[Sequence[str]] | None = None) -> Residuals:
        """The fix residuals of ``points`` on every run (or each on its ``scenarios``), as one sweep: the
        screen's probes and trials."""
        points, only = wanted(
            (p, self.all if scenarios is None else s)
            for p, s in zip(points, scenarios or [None] * len(points))
        )
        rows, _ = evaluate_points(self.space, points, self.client, [RESIDUALS], only)
        return residuals_in(rows, RESIDUALS)
