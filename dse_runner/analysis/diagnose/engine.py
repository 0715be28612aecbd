"""The diagnosis engine's stages: what every library's diagnosis runs, in order, on the fits of fitter.py.

Why one place: fitting each hypothesis alone, cross-validating and gating combinations, growing the answer
one hypothesis at a time, recalibrating it from many starts, judging each member, and proving searched
terms are statistics, not physics; a library supplies its hypotheses (their parameters and starts, which
are terms inside the model, which cannot share a set, which look alike); the combination screen between
:func:`singles` and :func:`cross_validated` is a strategy chosen by name (screens/). A fix here reaches
every library that runs these stages.

The stages, in a diagnosis' order: :func:`singles` (none and each hypothesis, every start scouted),
:func:`cross_validated` (the singles and a library's shortlisted combinations held out, the BIC gate),
:func:`grown` (one more while each pays its way), :func:`recalibrated` and :func:`judge_members`,
:func:`proven` and :func:`held_to_proof` (searched terms chosen again on each fold).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from scipy.stats import qmc

from ...sweeps.domain import Point
from ...sweeps.expand import key_of
from ...sweeps.fit import FitProblem, FitResult, Parameter
from ...sweeps.fit_rounds import evaluate_points, fit_all, residuals_in
from ...sweeps.spec import Space
from . import explain
from .explain import Candidate
from .fitter import MAX_ITERATIONS, Fitter, Messages, label, round_report
from .proof import Proof

SCOUTING = 6  # iterations every start of a fit gets before only the best start of each goes on
MAX_EFFECTS = 6  # the answer grows one hypothesis at a time, while each pays its way, up to this many
GROW_FINALISTS = 2  # sets of one more fitted on after scouting
LOWER = 1e-3  # a refit replaces an earlier fit of the same set when its SSE is lower by this share
RESTARTS = 64  # starts of the calibrated parameters a fit is refitted from (a Sobol' design)
REFITTED = 16  # ... of which the best few by their misfit are fitted, SCOUTING iterations each


class Screened(Protocol):
    """A combination a library's screen checked by simulation and shortlisted: its ids, its fit's label,
    where its fit starts and the BIC it was checked at."""

    ids: tuple[str, ...]
    label: str
    start: Mapping[str, float]
    bic: float


SURVIVORS = 2  # pairs that pass the BIC gate and are cross-validated, at most


def gated_early(
    short: Sequence[Screened],
    full: Mapping[tuple[str, ...], FitResult],
    count: int,
    margin: float = explain.BIC_MARGIN,
) -> list[Screened]:
    """The screened pairs sure to pass explain.bic_gate whatever the singles' cross-validation chooses:
    their checked BIC (which their fit can only lower) is ``margin`` below every single's and none's. Only
    pairs: a triple's parts include pairs, not fitted yet, which it must beat too."""
    lowest = min(explain.bic(f) for f in full.values())
    sure = [x for x in short if len(x.ids) == 2 and x.bic <= lowest - margin]
    return sorted(sure, key=lambda x: x.bic)[:count]


@dataclass
class Fits(Fitter):
    """The fitter (fitter.py) with the library's hypotheses: their parameters and starts, which of them are
    terms inside the model (and so pay for the search among them), which pairs cannot be in one set, and
    which leave residuals alike (a screen fits a shortlisted set's twins beside it). Each stage below asks
    it for its problems and their fits."""

    # id -> parameters, names, starts, start(k), term
    library: Mapping[str, Any] = field(default_factory=dict)
    shares: Callable[[str, str], bool] = lambda a, b: False  # two hypotheses that act on one thing
    look_alikes: Mapping[str, tuple[str, ...]] = field(default_factory=dict)  # id -> its declared twins
    min_gain: float = explain.MIN_GAIN  # the rule a set must pass: held-out error this much lower ...
    bic_margin: float = explain.BIC_MARGIN  # ... and the BIC this much lower
    survivors: int = SURVIVORS  # combinations that pass the BIC gate and are cross-validated, at most

    @property
    def parts(self) -> list[list[str]]:
        return self.validation.tests

    @property
    def terms(self) -> list[str]:
        """The terms inside the model the library offers, by name."""
        return [name for name, h in self.library.items() if h.term is not None]

    def candidate(self, ids: tuple[str, ...], fit: FitResult) -> Candidate:
        """A fitted set as a candidate, charged for the search of the terms inside the model it chose among
        every term offered (explain.search_charge); the signal effects are a short list named beforehand."""
        chosen = sum(1 for name in ids if self.library[name].term is not None)
        return Candidate(ids, fit, charge=explain.search_charge(len(self.terms), chosen))


def singles(f: Fits) -> tuple[list[tuple[str, ...]], dict[tuple[str, ...], FitResult]]:
    """No effect and each effect alone, fitted on every scenario: every start of an effect scouted for a few
    iterations, then only the best start of each fitted on (after a few iterations each start is in its
    basin)."""
    library = f.library
    sets = [(), *((name,) for name in library)]
    starts = {
        s: [library[s[0]].start(i) for i in range(len(library[s[0]].starts))] if s else [{}] for s in sets
    }
    tries = [
        f.problem(f"{label(s)}#{i}", s, f.scenarios, v, SCOUTING)
        for s in sets
        for i, v in enumerate(starts[s])
    ]
    f.say(
        f"fitting {len(sets) - 1} effects and none on every scenario: {len(tries)} fits, "
        f"{SCOUTING} iterations from every start"
    )
    tried = f.fit(tries)
    scouted = {
        s: min((tried[f"{label(s)}#{i}"] for i in range(len(starts[s]))), key=lambda fit: fit.sse)
        for s in sets
    }
    going = [
        f.problem(label(s), s, f.scenarios, fit.values, f.iterations - SCOUTING)
        for s, fit in scouted.items()
        if not fit.converged
    ]
    f.say(f"going on from the best start: {len(going)} fits")
    went = f.fit(going)
    return sets, {s: went.get(label(s), fit) for s, fit in scouted.items()}


def cross_validated(
    f: Fits,
    sets: list[tuple[str, ...]],
    full: Mapping[tuple[str, ...], FitResult],
    short: list[Screened],
) -> tuple[Candidate, list[Candidate]]:
    """None, each single and the shortlisted pairs as candidates, judged on held-out error: the pairs fitted
    on every scenario, and cross-validated where they may pass the BIC gate. The baseline (no effect), and
    every candidate."""
    parts = f.parts
    # pairs whose checked point alone already passes the BIC gate (a fit only lowers the SSE) are
    # cross-validated beside their full fits, saving the rounds of a batch of their own
    early = gated_early(short, full, f.survivors, f.bic_margin) if parts else []
    folded = [p for s in sets for p in f.by_fold(s, full[s].values)]
    folded += [p for x in early for p in f.by_fold(x.ids, x.start)]
    combos = [f.problem(x.label, x.ids, f.scenarios, x.start) for x in short]
    f.say(
        f"cross-validating: {len(parts)} folds, {len(folded)} fits"
        + (f"; fitting {len(combos)} pairs" if combos else "")
    )
    results = f.fit(folded + combos)
    candidates = [f.candidate(s, full[s]) for s in sets]
    combinations = [f.candidate(x.ids, results[x.label]) for x in short]
    first = {x.label for x in early}
    f.hold_out(candidates + [c for c in combinations if c.label in first], results)
    if not parts:  # one run: judged on its fit alone, as every candidate is
        f.hold_out(combinations, {})
    baseline = candidates[0]
    current = explain.select(candidates[1:], baseline, f.min_gain, f.bic_margin)
    everything = candidates + combinations
    survivors = (
        explain.bic_gate(combinations, everything, current, f.bic_margin, f.survivors) if parts else []
    )
    late = [c for c in survivors if not c.validated]
    if late:
        f.say(f"cross-validating {', '.join(c.label for c in late)}")
        more = f.fit([p for c in late for p in f.by_fold(c.ids, c.full.values)])
        f.hold_out(late, more)
    return baseline, everything


def grown(
    f: Fits,
    selected: Candidate,
    full: Mapping[tuple[str, ...], FitResult],
    everything: list[Candidate],
    noise_factor: float,
    floor: float = 1.0,
    most: int = MAX_EFFECTS,
) -> tuple[Candidate, list[dict[str, Any]]]:
    """``selected`` grown one effect at a time while each pays its way, the held-out error stays above
    ``noise_factor`` noise floors (``floor``: in the held-out error's units; 1 where the residuals are in
    noise units) and the answer has fewer than ``most`` effects; the answer, and what each round of growth
    tried. Every candidate fitted joins ``everything``."""
    growth: list[dict[str, Any]] = []
    while (
        selected.ids
        and len(selected.ids) < most
        and explain.above_floor(selected.cross_validated, floor, noise_factor)
    ):
        grown = extended(f, selected, full, everything, growth)
        if grown is None:
            break
        f.say(f"grown: {grown.label}, held-out {grown.cross_validated:.3g}")
        selected = grown
    return selected, growth


def restarts(base: Sequence[Parameter], point: Point, settings: Sequence[Point] = ()) -> list[Point]:
    """Where a fit of the calibrated parameters ``base`` restarts from, around ``point``: a Sobol' design of
    RESTARTS points over every calibrated parameter's range, for ``point`` and for each of ``settings`` (its
    effects from their own starts: a friction's narrower widths); and for each pair of calibrated parameters
    a design over the two alone, the rest as at ``point`` (an initial position and velocity a slide apart,
    which the full design seldom meets)."""
    spread = [p.upper - p.lower for p in base]
    whole = qmc.Sobol(len(base), scramble=True, seed=0).random(RESTARTS)
    points = [
        {**setting, **{p.name: p.lower + u * w for p, u, w in zip(base, row, spread)}}
        for setting in (point, *settings)
        for row in whole
    ]
    two = qmc.Sobol(2, scramble=True, seed=0).random(RESTARTS)
    for i, j in itertools.combinations(range(len(base)), 2):
        a, b = base[i], base[j]
        points += [
            {**point, a.name: a.lower + u * spread[i], b.name: b.lower + v * spread[j]} for u, v in two
        ]
    return points


def best_of(
    space: Space,
    client,
    residuals: str | Mapping[str, float],
    points: Sequence[Point],
    problem: Callable[[str, Mapping[str, float], int], FitProblem],
    scenarios: Sequence[str],
    say: Messages,
) -> FitResult:
    """The lowest fit from ``points``: the REFITTED of least misfit (one sweep simulates them all) each fitted
    for SCOUTING iterations, the best GROW_FINALISTS of those fitted on; ``problem(label, start, iterations)``
    makes each fit. Why: in a rugged misfit (an oscillator's frequency, an open-loop drift) the best start by
    its misfit alone is often not in the deepest basin, and a few iterations tell which are."""
    columns = [residuals] if isinstance(residuals, str) else list(residuals)
    rows, _ = evaluate_points(space, list(points), client, columns, [set(scenarios)] * len(points))
    found = residuals_in(rows, residuals)
    best = sorted(points, key=lambda point: screen_sse(point, scenarios, found))[:REFITTED]
    report = round_report(say)
    scouted = fit_all(
        space, [problem(f"#{k}", p, SCOUTING) for k, p in enumerate(best)], client, residuals, report
    )
    finalists = sorted(scouted.values(), key=lambda fit: fit.sse)[:GROW_FINALISTS]
    going = [problem(f"#{k}+", fit.values, MAX_ITERATIONS - SCOUTING) for k, fit in enumerate(finalists)]
    went = fit_all(
        space, [g for g, fit in zip(going, finalists) if not fit.converged], client, residuals, report
    )
    return min([*scouted.values(), *went.values()], key=lambda fit: fit.sse)


def recalibrated(f: Fits, answer: Candidate, everything: list[Candidate]) -> Candidate:
    """The answer with its calibrated parameters sought again, the effects in place: from every start of
    :func:`restarts` (the effects as fitted, and each member from its own starts), by :func:`best_of`.
    Why: the calibration was made with the model that lacked them, and bent its parameters to make up (a
    mass at its bound, an initial state a slide away from the true one); a fit from there can stay in that
    basin. The refit replaces the answer's fit, and is cross-validated, when its SSE over every scenario is
    lower by LOWER."""
    if not answer.ids or not f.base:
        return answer
    settings = [
        {**answer.full.point, **f.library[member].start(k)}
        for member in answer.ids
        for k in range(len(f.library[member].starts))
    ]
    points = restarts(f.base, answer.full.point, settings)
    f.say(
        f"recalibrating {answer.label}: {len(points)} starts of the calibrated parameters, "
        "the effects in place"
    )
    name = f"{answer.label}/recalibrated"
    fit = best_of(
        f.space,
        f.client,
        f.residuals,
        points,
        lambda tag, start, iterations: f.problem(f"{name}{tag}", answer.ids, f.scenarios, start, iterations),
        f.scenarios,
        f.say,
    )
    if not fit.sse < answer.full.sse * (1.0 - LOWER):
        return answer
    again = f.candidate(answer.ids, fit)
    f.hold_out([again], f.fit(f.by_fold(answer.ids, fit.values)) if f.parts else {})
    f.say(f"recalibrated: held-out {answer.cross_validated:.3g} -> {again.cross_validated:.3g} noise floors")
    everything[:] = [c for c in everything if c is not answer] + [again]
    return again


def joining(f: Fits, full: Mapping[tuple[str, ...], FitResult], h: str) -> dict[str, float]:
    """Where an effect joining a set starts: its single fit, unless that did no better than none (an effect
    another masks, such as the second side of a clip: alone it fitted to nothing), then its own first
    start."""
    single = full[(h,)]
    if single.error is None and explain.bic(single) < explain.bic(full[()]):
        return {n: single.values[n] for n in f.library[h].names}
    return f.library[h].start(0)


def extended(
    f: Fits,
    current: Candidate,
    full: Mapping[tuple[str, ...], FitResult],
    everything: list[Candidate],
    growth: list[dict[str, Any]],
) -> Candidate | None:
    """The best of ``current`` with one more effect (scouted from ``current``'s fit and the effect's single
    fit, the best few fitted on), cross-validated: it, if it beats ``current`` and every fitted part of
    itself; else None. What it tried joins ``everything``, and a line on it ``growth``."""
    library = f.library
    known = {frozenset(c.ids) for c in everything}
    sets = [
        tuple(sorted((*current.ids, h)))
        for h in library
        if h not in current.ids and not any(f.shares(h, i) for i in current.ids)
    ]
    sets = [x for x in sets if frozenset(x) not in known]
    if not sets:
        return None
    starts = {
        x: {
            **current.full.values,
            **{k: v for h in x if h not in current.ids for k, v in joining(f, full, h).items()},
        }
        for x in sets
    }
    f.say(f"growing {current.label}: {len(sets)} sets with one more effect, {SCOUTING} iterations each")
    scouted = f.fit([f.problem("+".join(x), x, f.scenarios, starts[x], SCOUTING) for x in sets])
    finalists = sorted(sets, key=lambda x: scouted["+".join(x)].sse)[:GROW_FINALISTS]
    going = [
        f.problem("+".join(x), x, f.scenarios, scouted["+".join(x)].values, f.iterations - SCOUTING)
        for x in finalists
        if not scouted["+".join(x)].converged
    ]
    fitted = {**scouted, **f.fit(going)}
    tried = [f.candidate(x, fitted["+".join(x)]) for x in sets]
    everything.extend(tried)
    best = min(tried, key=lambda c: c.bic)
    growth.append({"parent": current.label, "tried": len(tried), "best": best.label, "bic": best.bic})
    if best.bic > current.bic - f.bic_margin:
        return None
    f.hold_out([best], f.fit(f.by_fold(best.ids, best.full.values)) if f.parts else {})
    growth[-1]["held_out"] = best.cross_validated
    if explain.beats(best, current, f.min_gain, f.bic_margin) and explain.beats_subsets(
        best, everything, f.min_gain, f.bic_margin
    ):
        growth[-1]["accepted"] = True
        return best
    return None


def judge_members(f: Fits, answer: Candidate, everything: list[Candidate]) -> None:
    """Each set of the answer without one member, fitted from the answer's fit and cross-validated: the noise
    rule weighs every member by what taking it out costs, and keeps one it cannot weigh. A set fitted before
    (from its own starts) is replaced when the answer's fit leads it lower: else a member that only made up
    for a part's poor optimum (a term beside the one that fits, at a coefficient near 0) would be claimed."""
    if len(answer.ids) < 2 or not f.parts:
        return
    known = {frozenset(c.ids): c for c in everything}
    missing = [tuple(i for i in answer.ids if i != m) for m in answer.ids]
    f.say(f"judging each member of {answer.label}: {len(missing)} sets without one, fitted from its fit")
    fitted = f.fit(
        [f.problem(f"{label(x)}/judged", x, f.scenarios, dict(answer.full.values)) for x in missing]
    )
    better = [
        x
        for x in missing
        if frozenset(x) not in known
        or not known[frozenset(x)].validated
        or fitted[f"{label(x)}/judged"].sse < known[frozenset(x)].full.sse * (1.0 - LOWER)
    ]
    if not better:
        return
    folded = f.fit([p for x in better for p in f.by_fold(x, fitted[f"{label(x)}/judged"].values)])
    judged = [f.candidate(x, fitted[f"{label(x)}/judged"]) for x in better]
    f.hold_out(judged, folded)
    replaced = {frozenset(x) for x in better}
    everything[:] = [c for c in everything if frozenset(c.ids) not in replaced] + judged


def proven(f: Fits, answer: Candidate, full: Mapping[tuple[str, ...], FitResult]) -> Proof | None:
    """The answer's terms inside the model chosen again on each fold's fitting scenarios alone: each term in
    turn, every offered term in its place fitted there (SCOUTING iterations, the best fitted on, judged by
    the BIC), then the fold's choice predicts the fold's held-out scenarios. Why: a term picked among many on
    all the data has seen the held-out scenarios; only a choice made without them is proof. None when the
    answer has no term or nothing can be held out."""
    terms = tuple(i for i in answer.ids if f.library[i].term is not None)
    if not terms or not f.parts or len(answer.folds) != len(f.validation.folds):
        return None
    offered = f.terms
    proof = Proof(terms, offered=len(offered))
    f.say(f"proving {', '.join(terms)}: chosen again among {len(offered)} terms on each fold's fitting part")
    sets = [tuple(answer.ids) for _ in f.validation.folds]
    fits = list(answer.folds)
    for term in terms:
        problems, options = [], []
        for k, fold in enumerate(f.validation.folds):
            others = [i for i in sets[k] if i != term]
            choices = [o for o in offered if o not in others and not any(f.shares(o, i) for i in others)]
            options.append({o: tuple(sorted((*others, o))) for o in choices})
            start = dict(fits[k].values)
            problems += [
                f.problem(
                    f"{label(ids)}/proof{k}", ids, fold.train, {**start, **joining(f, full, o)}, SCOUTING
                )
                for o, ids in options[k].items()
            ]
        scouted = f.fit(problems)
        going = []
        for k in range(len(f.validation.folds)):
            best = min(options[k].values(), key=lambda ids: explain.bic(scouted[f"{label(ids)}/proof{k}"]))
            sets[k] = best
            fit = scouted[f"{label(best)}/proof{k}"]
            if not fit.converged:
                going.append(
                    f.problem(
                        f"{label(best)}/proof{k}",
                        best,
                        f.validation.folds[k].train,
                        fit.values,
                        f.iterations - SCOUTING,
                    )
                )
            fits[k] = fit
        went = f.fit(going)
        fits = [went.get(f"{label(sets[k])}/proof{k}", fit) for k, fit in enumerate(fits)]
    proof.chosen = [tuple(i for i in ids if f.library[i].term is not None) for ids in sets]
    rows = f.rows([(fit.point, fold.test) for fit, fold in zip(fits, f.folds)])
    for fit, fold in zip(fits, f.folds):
        for scenario in fold.test:
            proof.held_out[scenario] = f.score(rows.get((key_of(fit.point), scenario)))
    f.say(
        f"proven: {proof.agree} of {len(fits)} folds chose {', '.join(terms)} again; held-out "
        f"{answer.cross_validated:.3g} as chosen on all data, {proof.error:.3g} as each fold chose"
    )
    return proof


def held_to_proof(
    f: Fits,
    chosen: Candidate,
    proof: Proof | None,
    everything: list[Candidate],
    baseline: Candidate,
    dropped: list[explain.Dropped],
) -> Candidate:
    """``chosen``, or without its terms (into ``dropped``) unless the choice each fold made of them (the
    proof) still beats the answer without them by explain.MIN_GAIN; that set is fitted from the answer's
    fit and cross-validated if no stage did yet."""
    if proof is None:
        return chosen
    rest = tuple(i for i in chosen.ids if i not in proof.terms)
    without = baseline if not rest else fitted_set(everything, rest)
    if without is None:
        f.say(f"judging {', '.join(proof.terms)}: the answer without them, fitted from its fit")
        name = f"{label(rest)}/judged"
        fit = f.fit([f.problem(name, rest, f.scenarios, dict(chosen.full.values))])[name]
        without = f.candidate(rest, fit)
        f.hold_out([without], f.fit(f.by_fold(rest, fit.values)))
        everything.append(without)
    if proof.bears_out(without.cross_validated):
        return chosen
    reason = proof.failed(without.cross_validated, " noise floors")
    dropped.extend(explain.Dropped(t, math.nan, reason) for t in proof.terms)
    return without


def fitted_set(candidates: Sequence[Candidate], ids: Sequence[str]) -> Candidate | None:
    """The cross-validated candidate of exactly the effects ``ids``, if one was fitted."""
    return next((c for c in candidates if set(c.ids) == set(ids) and c.validated), None)


def screen_sse(point: Point, scenarios: Sequence[str], residuals) -> float:
    """The SSE of a simulated point on every run; infinite if any run failed."""
    found = [residuals(point, s) for s in scenarios]
    return math.inf if any(r is None for r in found) else float(sum(r @ r for r in found))
