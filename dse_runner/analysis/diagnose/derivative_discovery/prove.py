"""Sweeps for discovery: the sensitivities a proposal regresses on, and the fits, folds and held-out errors
that prove (or not) what it proposed, judged as the library's effects are (explain.py).

Why sweeps: every simulation goes through the same store and cluster as the calibration and the library's
fits, so a re-run resumes from the store and a term's proof is the very machinery its competitors had.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace

import numpy as np

from ....errors import DseError
from ....sweeps.domain import Point
from ....sweeps.expand import wanted
from ....sweeps.fit import FitProblem, FitResult, Parameter
from ....sweeps.fit_rounds import evaluate_points, fit_all, residuals_in
from ....sweeps.spec import Space, derived_space
from ..explain import Candidate
from ..validation import Fold, as_folds
from .library import CandidateTerm
from .propose import Regression

SWEEP = "diagnosis-derivative-terms"  # the sweep every discovery simulation goes to
PRUNE_SE = 2.0  # a fitted term within this many standard errors of zero is dropped

Report = Callable[[int, int, int, int], None]


def terms_space(space: Space, terms: Sequence[CandidateTerm]) -> Space:
    """``space`` with every candidate term a parameter at 0 (bit for bit the model without it), run as a
    plain sweep of given points."""
    parameters = {**space.spec.parameters, **{t.name: [0.0] for t in terms}}
    return derived_space(
        space,
        name=SWEEP,
        parameters=parameters,
        constraints=[],
        keep_trajectories=0,
        search=space.spec.search.model_copy(update={"strategy": "given"}),
    )


def inward(parameter: Parameter, value: float) -> float:
    """A finite-difference step of ``parameter`` from ``value``, turned inward at
    its upper bound (as fit.py's)."""
    return parameter.step if value + parameter.step <= parameter.upper else -parameter.step


def regression(
    space: Space,
    client,
    base: Point,
    freed: Sequence[Parameter],
    terms: Sequence[CandidateTerm],
    scales: Mapping[str, float],
    scenarios: Sequence[str],
    trial: float,
) -> Regression:
    """One sweep: ``base`` and, for every freed parameter and every candidate term, ``base`` moved by a small
    step; the residuals' change per unit of each is its sensitivity. The target is minus the residuals at
    ``base``: what the terms and parameters together should cancel. A term whose runs fail is left out."""
    steps = [(p.name, inward(p, float(base[p.name]))) for p in freed]
    steps += [(t.name, trial * t.scale) for t in terms]
    points = [base, *({**base, name: float(base.get(name, 0.0)) + step} for name, step in steps)]
    rows, _ = evaluate_points(space, points, client, list(scales))
    residuals = residuals_in(rows, scales)
    at_base = [residuals(base, s) for s in scenarios]
    if any(r is None for r in at_base):
        raise DseError(
            f"derivative discovery: the chosen point fails to simulate on "
            f"{', '.join(s for s, r in zip(scenarios, at_base) if r is None)}"
        )
    columns = []
    for point, (_, step) in zip(points[1:], steps):
        moved = [residuals(point, s) for s in scenarios]
        columns.append(
            np.full(sum(map(len, at_base)), np.nan)
            if any(m is None for m in moved)
            else np.concatenate([(m - r) / step for m, r in zip(moved, at_base)])
        )
    matrix = np.column_stack(columns) if columns else np.zeros((sum(map(len, at_base)), 0))
    good = np.isfinite(matrix).all(axis=0)
    fitted, term_columns = matrix[:, : len(freed)], matrix[:, len(freed) :]
    names = tuple(t.name for t, ok in zip(terms, good[len(freed) :]) if ok)
    run = np.concatenate([np.full(len(r), k) for k, r in enumerate(at_base)])
    return Regression(
        -np.concatenate(at_base),
        term_columns[:, good[len(freed) :]],
        fitted[:, good[: len(freed)]],
        run,
        names,
    )


def term_parameter(term: CandidateTerm, start: float, bound: float, trial: float) -> Parameter:
    """A term's coefficient as a fitted parameter: within ±``bound`` times what adds as much as its
    derivative, differenced at ``trial`` of that."""
    limit = bound * term.scale
    return Parameter(term.name, float(np.clip(start, -limit, limit)), -limit, limit, trial * term.scale)


def fit(
    space: Space,
    client,
    label: str,
    parameters: Sequence[Parameter],
    base: Point,
    scenarios: Sequence[str],
    scales: Mapping[str, float],
    max_iterations: int,
    report: Report | None,
) -> FitResult:
    """``parameters`` fitted on ``scenarios`` from ``base`` (which holds everything they do not free)."""
    return fit_sets(space, client, {label: parameters}, base, scenarios, scales, max_iterations, report)[
        label
    ]


def fit_sets(
    space: Space,
    client,
    sets: Mapping[str, Sequence[Parameter]],
    base: Point,
    scenarios: Sequence[str],
    scales: Mapping[str, float],
    max_iterations: int,
    report: Report | None,
) -> dict[str, FitResult]:
    """Several sets of parameters fitted in lockstep (fit_all: each round one sweep for all of them)."""
    problems = []
    for label, parameters in sets.items():
        names = {p.name for p in parameters}
        problems.append(
            FitProblem(
                label,
                tuple(parameters),
                {k: v for k, v in base.items() if k not in names},
                tuple(scenarios),
                max_iterations,
            )
        )
    return fit_all(space, problems, client, dict(scales), report) if problems else {}


def pruned(result: FitResult, names: Sequence[str], factor: float = PRUNE_SE) -> list[str]:
    """Of ``names`` (fitted terms), those at least ``factor`` cluster-robust standard errors from zero."""
    kept = []
    for name in names:
        se = result.standard_error.get(name, math.inf)
        if result.values[name] != 0.0 and math.isfinite(se) and abs(result.values[name]) >= factor * se:
            kept.append(name)
    return kept


def cross_validate(
    space: Space,
    client,
    jobs: Sequence[tuple[Candidate, Sequence[Parameter]]],
    base: Point,
    folds: Sequence[Fold],
    scales: Mapping[str, float],
    max_iterations: int,
    report: Report | None,
) -> None:
    """Each candidate refitted on each fold's training scenarios (from its full fit) and scored on its test
    scenarios: the RMS of its noise-scaled residuals per held-out scenario, into its ``held_out``. One
    lockstep of fits for all candidates and folds, one sweep for all held-out runs."""
    problems, owners = [], []
    for c, parameters in jobs:
        names = {p.name for p in parameters}
        start = c.full.values
        freed = tuple(replace(p, start=start.get(p.name, p.start)) for p in parameters)
        fixed = {k: v for k, v in {**base, **c.full.point}.items() if k not in names}
        for k, fold in enumerate(folds):
            problems.append(FitProblem(f"{c.label}/fold{k}", freed, fixed, fold.train, max_iterations))
            owners.append((c, fold.test))
    results = fit_all(space, problems, client, dict(scales), report)
    points, only = wanted((results[p.label].point, fold) for p, (_, fold) in zip(problems, owners))
    rows, _ = evaluate_points(space, points, client, list(scales), only)
    residuals = residuals_in(rows, scales)
    for problem, (c, fold) in zip(problems, owners):
        result = results[problem.label]
        c.folds.append(result)
        for scenario in fold:
            r = residuals(result.point, scenario)
            c.held_out[scenario] = float(np.sqrt(np.mean(r**2))) if r is not None and r.size else math.inf


def baseline_candidate(
    space: Space,
    client,
    freed: Sequence[Parameter],
    base: Point,
    scales: Mapping[str, float],
    folds: Sequence[Sequence[str] | Fold],
    max_iterations: int = 30,
    report: Report | None = None,
) -> Candidate:
    """The answer without any term, for a diagnosis that has none yet: ``freed`` fitted on every scenario from
    ``base``, then cross-validated on ``folds`` (as discover_derivatives takes them)."""
    scenarios = [s.name for s in space.scenarios]
    folds = as_folds(folds, scenarios)
    candidate = Candidate(
        (), fit(space, client, "none", freed, base, scenarios, scales, max_iterations, report)
    )
    if folds:
        cross_validate(space, client, [(candidate, freed)], base, folds, scales, max_iterations, report)
    return candidate
