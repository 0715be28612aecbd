"""Discovery beyond the library: a sparse correction to a model-exchange instance's state derivatives.

Why: when no signal effect explains what a model misses, the cause is often in its equations: a term they
lack. The master integrates model-exchange FMUs itself and can add terms to their derivatives
(simulation/derivative_terms.py), so a missing term can be proposed, fitted and proven from the recordings
without touching the FMU, by the same sweeps, folds and BIC as the library's effects:

1. observe: the chosen fit's runs, simulated here, recording every state, derivative and real input;
2. library: candidate terms (library.py), each on a state's derivative, sized along those runs;
3. propose: one sweep of the terms' sensitivities, then PySINDy's STLSQ on the residuals the chosen fit
   leaves, the fit's own parameters projected out (propose.py): a ranking, first order only;
4. fit: forward selection among the best-ranked terms, each fitted jointly with the chosen fit's parameters
   (fit_all: every round one sweep for all): the term whose fit has the lowest BIC joins, while it lowers the
   BIC by the rule's margin and stands two standard errors from zero. The fits, not the first-order ranking,
   decide between look-alikes (x³ and x·|x| both stiffen a spring);
5. prove: folds of scenarios and the BIC against the chosen answer (explain.beats): the terms are claimed
   only if they lower the held-out error clearly and pay for their parameters.

:func:`discover_derivatives` takes what a diagnosis has at hand (the space its fits ran in, the cluster's
client, the chosen candidate and the parameters it freed, the residual scales, the folds) and returns a
:class:`Discovered` or a :class:`NotDiscovered` with its reason.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ....simulation.run import simulate
from ....sweeps.domain import Point
from ....sweeps.fit import FitResult, Parameter
from ....sweeps.spec import Space
from .. import explain
from ..explain import Candidate
from ..validation import Fold, as_folds
from .library import CandidateTerm, ModelExchangeInstance, candidate_terms, model_exchange_instances
from .propose import Proposal, propose
from .prove import (
    PRUNE_SE,
    baseline_candidate,
    cross_validate,
    fit_sets,
    pruned,
    regression,
    term_parameter,
    terms_space,
)

DISCOVERED = "discovered"  # the candidate id, and the effect id in the JSON
Say = Callable[[str], None]


@dataclass(frozen=True)
class Settings:
    degree: int = 3  # monomials of states and inputs up to this degree
    max_terms: int = 3  # at most this many terms claimed
    screen: int = 3  # the proposal's best this many terms are fitted, one more at a time (forward selection)
    trial: float = 0.003  # a sensitivity's step: the term adding this share of its derivative's RMS
    bound: float = 3.0  # a coefficient may add at most this many times its derivative's RMS
    bootstrap: int = 30  # scenario resamples
    inclusion: float = 0.7  # share of the resamples a term must be picked in
    seed: int = 0  # the bootstrap's: a re-run proposes the same and resumes from the store
    max_iterations: int = 30
    min_gain: float = explain.MIN_GAIN
    bic_margin: float = explain.BIC_MARGIN


@dataclass
class Discovered:
    """Terms the recordings support, fitted jointly with the chosen answer's
    parameters and proven on folds."""

    terms: dict[str, CandidateTerm]  # parameter name -> term
    candidate: Candidate  # the chosen answer with the terms: its full fit, folds and held-out errors
    baseline: Candidate  # the chosen answer without them
    proposal: Proposal
    seconds: dict[str, float] = field(default_factory=dict)
    rejected: dict[str, str] = field(default_factory=dict)  # sets of terms that could not be fitted, and why

    @property
    def coefficients(self) -> dict[str, float]:
        return {name: self.candidate.full.values[name] for name in self.terms}

    @property
    def intervals(self) -> dict[str, tuple[float, float]]:
        """About 95 %, cluster-robust over scenarios (fit.py)."""
        found = self.candidate.full.interval()
        return {name: found[name] for name in self.terms}

    @property
    def held_out(self) -> tuple[float, float]:
        """Held-out error without the terms and with them, in noise floors."""
        return self.baseline.cross_validated, self.candidate.cross_validated

    def effects(self) -> list[dict[str, Any]]:
        """One entry per corrected derivative: ``{"id": "discovered", "target": "msd.der(v)", "terms":
        {"x^3": -60.1}, "intervals": ..., "parameters": ..., "readable": "der(v) += -60.1·x^3"}``."""
        coefficients, intervals = self.coefficients, self.intervals
        targets: dict[str, list[str]] = {}
        for name, term in self.terms.items():
            targets.setdefault(term.target, []).append(name)
        return [
            {
                "id": DISCOVERED,
                "target": target,
                "terms": {self.terms[n].term.text: coefficients[n] for n in names},
                "intervals": {self.terms[n].term.text: [float(v) for v in intervals[n]] for n in names},
                "parameters": {n: coefficients[n] for n in names},
                "readable": readable(
                    self.terms[names[0]].state, {self.terms[n].term.text: coefficients[n] for n in names}
                ),
            }
            for target, names in targets.items()
        ]

    def to_json(self) -> dict[str, Any]:
        before, after = self.held_out
        return {
            "effects": self.effects(),
            "held_out_before": before,
            "held_out_after": after,
            "bic_before": self.baseline.bic,
            "bic_after": self.candidate.bic,
            "proposed": self.proposal.terms,
            "rejected": self.rejected,
            "seconds": self.seconds,
        }


@dataclass
class NotDiscovered:
    """Why no term is claimed; what was proposed and tried, when it got that far."""

    reason: str
    proposal: Proposal | None = None
    tried: Candidate | None = None
    baseline: Candidate | None = None
    seconds: dict[str, float] = field(default_factory=dict)
    rejected: dict[str, str] = field(default_factory=dict)  # sets of terms that could not be fitted, and why

    def to_json(self) -> dict[str, Any]:
        return {
            "effects": [],
            "reason": self.reason,
            "rejected": self.rejected,
            "proposed": self.proposal.terms if self.proposal else {},
            "held_out_before": self.baseline.cross_validated if self.baseline else None,
            "held_out_tried": self.tried.cross_validated if self.tried else None,
            "seconds": self.seconds,
        }


def readable(state: str, terms: Mapping[str, float]) -> str:
    """``der(v) += -60.1·x^3 + 0.12·v*abs(v)``."""
    parts = [f"{value:.4g}·{text}" if text != "1" else f"{value:.4g}" for text, value in terms.items()]
    return f"der({state}) += " + " + ".join(parts).replace("+ -", "- ")


def observe(
    space: Space, point: Point, instances: Sequence[ModelExchangeInstance], names: Sequence[str] | None = None
) -> list[dict[str, np.ndarray]]:
    """Every scenario (of ``names``, when given) simulated here at ``point``, recording each instance's
    states, derivatives and real inputs: what the library sizes its terms on."""
    plan = space.plan.recording([ref for i in instances for ref in i.recorded], "derivative discovery")
    return [
        simulate(plan, scenario, point, objectives={}, experiment=space.experiment).outputs
        for scenario in space.scenarios
        if names is None or scenario.name in names
    ]


def fitted_error(fit: FitResult) -> dict[str, float]:
    """With a single scenario no fold can be held out: its fitted RMS stands in (optimistic, and said so)."""
    return {"fitted": explain.fitted_rms(fit)}


__all__ = [
    "DISCOVERED",
    "Discovered",
    "NotDiscovered",
    "Settings",
    "baseline_candidate",
    "discover_derivatives",
]


def forward(
    space: Space,
    client,
    freed: Sequence[Parameter],
    screened: Mapping[str, CandidateTerm],
    start: Mapping[str, float],
    base: Point,
    scenarios: Sequence[str],
    scales: Mapping[str, float],
    reference: FitResult,
    settings: Settings,
    report: Callable | None,
    rejected: dict[str, str],
) -> tuple[FitResult | None, list[str]]:
    """Forward selection: fit the terms chosen so far plus each other screened term (in lockstep); the set of
    least BIC is kept if it lowers the BIC by ``settings.bic_margin`` and its every term stands PRUNE_SE
    standard errors from zero; repeat up to ``settings.max_terms``. None when no term joins. A set whose fit
    cannot start (its start fails to simulate: a solver limit, NaN, divergence) goes into ``rejected``."""
    names: list[str] = []
    current, start = reference, dict(start)
    while len(names) < settings.max_terms:
        options = {f"{DISCOVERED}:{'+'.join([*names, n])}": [*names, n] for n in screened if n not in names}
        if not options:
            break
        sets = {
            label: (
                *(replace(p, start=current.values.get(p.name, p.start)) for p in freed),
                *(term_parameter(screened[n], start[n], settings.bound, settings.trial) for n in terms),
            )
            for label, terms in options.items()
        }
        results = fit_sets(space, client, sets, base, scenarios, scales, settings.max_iterations, report)
        rejected.update({key: r.error for key, r in results.items() if r.error})
        label = min(results, key=lambda key: explain.bic(results[key]))
        best = results[label]
        if (
            explain.bic(best) > explain.bic(current) - settings.bic_margin
            or pruned(best, options[label]) != options[label]
        ):
            break
        names, current = options[label], best
        start.update({n: best.values[n] for n in names})
    return (current if names else None), names


def discover_derivatives(
    space: Space,
    client,
    chosen: Candidate,
    freed: Sequence[Parameter],
    scales: Mapping[str, float],
    folds: Sequence[Sequence[str] | Fold],
    settings: Settings = Settings(),
    say: Say | None = None,
    fitted: Sequence[str] | None = None,
    pieces: Sequence[str] | None = None,
) -> Discovered | NotDiscovered:
    """Terms for the model-exchange instances' derivatives that the recordings support beyond ``chosen``.

    ``space``: the space ``chosen`` was fitted in (its objectives hold the residuals named in ``scales``, each
    multiplied by its scale: noise floors); ``freed``: the parameters ``chosen`` fitted, refitted with the
    terms; ``folds``: scenario names per fold, each judged by a fit on the others, or validation.Fold (none:
    a single scenario, judged on its fit); ``fitted``: the scenarios a fit on everything uses, and ``pieces``
    those that partition its data, which the proposal holds out one at a time (default: every scenario).
    ``chosen`` is cross-validated here if it was not yet."""
    say = say or (lambda message: None)
    seconds: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(stage: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        seconds[stage] = round(now - clock, 3)
        clock = now

    instances = model_exchange_instances(space.plan)
    if not instances:
        return NotDiscovered(
            "no model-exchange instance: co-simulation FMUs integrate their own states, so the "
            "master cannot add to their derivatives; what remains points inside them",
            baseline=chosen,
        )
    scenarios = tuple(fitted) if fitted is not None else tuple(s.name for s in space.scenarios)
    folds = as_folds(folds, scenarios)
    runs = observe(space, chosen.full.point, instances, scenarios)
    library = [t for i in instances for t in candidate_terms(i, runs, settings.degree)]
    lap("observe")
    if not library:
        return NotDiscovered(
            "no candidate term: every state's derivative is kinematic or nothing varies",
            baseline=chosen,
            seconds=seconds,
        )
    by_name = {t.name: t for t in library}
    work = terms_space(space, library)
    base = {**chosen.full.point, **{t.name: 0.0 for t in library}}
    freed = tuple(replace(p, start=chosen.full.values.get(p.name, p.start)) for p in freed)
    say(
        f"derivative discovery: {len(library)} candidate terms on "
        f"{', '.join(sorted({t.target for t in library}))}: one sweep of their sensitivities"
    )
    proposal = propose(
        regression(work, client, base, freed, library, scales, tuple(pieces or scenarios), settings.trial),
        settings.max_terms,
        settings.bootstrap,
        settings.inclusion,
        settings.seed,
    )
    lap("propose")
    if proposal.empty:
        return NotDiscovered(
            "no candidate term predicts the residuals of held-out scenarios better than none "
            "(STLSQ, leave one scenario out)",
            proposal,
            baseline=chosen,
            seconds=seconds,
        )

    def report(round_: int, active: int, points: int, simulations: int) -> None:
        say(f"discovery fits: round {round_}, {active} active, {points} points, {simulations} simulations")

    screened = [name for name, _ in proposal.ranked][: settings.screen]
    say(
        f"derivative discovery: ranked first {', '.join(screened)}; forward selection, each fitted with "
        f"{', '.join(p.name for p in freed) or 'nothing else'}"
    )
    rejected: dict[str, str] = {}
    result, names = forward(
        work,
        client,
        freed,
        {n: by_name[n] for n in screened},
        dict(proposal.ranked),
        base,
        scenarios,
        scales,
        chosen.full,
        settings,
        report,
        rejected,
    )
    if rejected:
        say(
            f"derivative discovery: rejected {len(rejected)} sets of terms whose fit could not start "
            f"({next(iter(rejected.values()))})"
        )
    if result is None:
        lap("fit")
        return NotDiscovered(
            f"no proposed term ({', '.join(screened)}), fitted, lowered the BIC by "
            f"{settings.bic_margin:g} and stood {PRUNE_SE:g} standard errors from zero",
            proposal,
            baseline=chosen,
            seconds=seconds,
            rejected=rejected,
        )
    parameters = (
        *(replace(p, start=result.values[p.name]) for p in freed),
        *(term_parameter(by_name[n], result.values[n], settings.bound, settings.trial) for n in names),
    )
    lap("fit")
    found = Candidate((*chosen.ids, DISCOVERED), result)
    baseline = chosen if chosen.held_out else Candidate(chosen.ids, chosen.full)
    if folds:
        jobs = [(found, parameters)] + ([] if chosen.held_out else [(baseline, freed)])
        say(f"derivative discovery: cross-validating on {len(folds)} folds")
        cross_validate(work, client, jobs, base, folds, scales, settings.max_iterations, report)
    else:
        found.held_out = fitted_error(found.full)
        baseline.held_out = baseline.held_out or fitted_error(baseline.full)
    lap("prove")
    if explain.beats(found, baseline, settings.min_gain, settings.bic_margin):
        return Discovered({n: by_name[n] for n in names}, found, baseline, proposal, seconds, rejected)
    return NotDiscovered(
        f"{' + '.join(by_name[n].term.text for n in names)} did not beat the answer "
        f"without it: held-out {baseline.cross_validated:.3g} -> "
        f"{found.cross_validated:.3g} noise floors (needs {settings.min_gain:.0%} lower), "
        f"BIC {baseline.bic:.1f} -> {found.bic:.1f} (needs {settings.bic_margin:g} lower)",
        proposal,
        found,
        baseline,
        seconds,
        rejected,
    )
