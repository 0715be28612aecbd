"""Discovery beyond a library: terms proposed on each fold's own fitting scenarios, settled, proven and
accepted by the library's rule with the search charged, written once for every case.

Why: when a library's answer still leaves error above the noise, a case may search a space of terms for
what it lacks (the Robotti's correction block, equation error's sparse regression). The statistics of that
search are not the case's: a term chosen on all the data has seen the scenarios it is judged on, so each
fold proposes and fits its own (proof.Proof); terms within a few standard errors of zero go and their slots
are refilled from the proposal's ranking (:func:`settle`); the answer with terms must beat the answer
without them by the library's rule with the BIC margin raised for the search (:func:`accept`); and what the
terms do is compared with the library's own effects (:func:`resembles`). A case supplies only the search
(term_search.TermSearch): how terms are proposed from a parent fit, which parameter each term is, and how
they are freed in a fit problem.

The procedure (:func:`discover`), on top of the reference answer R:
1. propose terms for R + D (and D alone when R has effects: a term may explain what R only looked like),
   from every scenario and from each fold's fitting scenarios, and rank them on the parents' residuals
   (term_ranking.py);
2. fit each on every scenario, settle them;
3. fit each fold's own proposal on its fitting scenarios and score its held-out ones: the proof;
4. accept the best candidate the rule and the proof bear out, or none.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...sweeps.domain import Point
from ...sweeps.fit import FitProblem, FitResult
from . import explain
from .explain import Candidate
from .fitter import Fitter
from .proof import Proof
from .sparse_regression import PRUNE_SE
from .term_ranking import ranked as ranked_on_residuals
from .term_search import Parent, Proposal, TermSearch

DISCOVERED = "discovered"  # the id discovered terms take among a candidate's ids
RESEMBLES, PARTLY = 0.9, 0.5  # cosine similarity above which terms resemble, partly resemble, an effect


def library_ids(ids: Sequence[str]) -> tuple[str, ...]:
    """A candidate's library effects: its ids without the discovered terms."""
    return tuple(h for h in ids if h != DISCOVERED)


def refilled(
    kept: Mapping[str, float], proposal: Proposal, tried: set[str], max_terms: int
) -> dict[str, float]:
    """The kept terms (at zero: the dropped ones may have balanced them) and, in the slots pruning freed, the
    next terms the proposal ranked that were not tried yet (at their proposed values). A proposal's ranking
    may see more than the fit does, so a term it ranks high may fall when fitted; its slot is then the next
    term's, not lost."""
    out = {v: 0.0 for v in kept}
    for variable, value in proposal.ranked:
        if len(out) >= max_terms:
            break
        if variable not in out and variable not in tried:
            out[variable] = value
    return out


def settle(
    f: Fitter,
    search: TermSearch,
    jobs: Mapping[str, tuple[Callable[[Mapping[str, float]], FitProblem], Proposal]],
    what: str,
) -> dict[str, FitResult | None]:
    """Fit each job's proposed terms, prune those within PRUNE_SE standard errors of zero, refit with the
    freed slots refilled (:func:`refilled`; all of them when no term survived), then prune and refit
    without refilling until every term stands; lockstep batches throughout. ``jobs``: label -> (problem
    for given terms, proposal). None where no term survives."""
    fits = f.fit([make(dict(proposal.terms)) for make, proposal in jobs.values()], what)
    tried = {label: set(proposal.terms) for label, (_, proposal) in jobs.items()}
    out: dict[str, FitResult | None] = {}
    for refill in (True, *[False] * search.max_terms):  # without refilling each pass drops a term: it ends
        again = []
        for label, (make, proposal) in jobs.items():
            if label in out:
                continue
            fit = fits[label]
            kept = search.standing(fit)
            if kept == search.terms_of(fit):
                continue  # settled: every term stands
            terms = (
                refilled(kept, proposal, tried[label], search.max_terms) if refill else {v: 0.0 for v in kept}
            )
            if not terms:
                out[label] = None  # nothing survived, and nothing is left to try
                continue
            tried[label] |= set(terms)
            again.append(make(terms))
        if not again:
            break
        fits.update(f.fit(again, f"{what}: refitting without the terms near zero"))
    return {label: out.get(label, fits[label]) for label in jobs}


@dataclass
class Discovery:
    """What discovery tried on top of ``reference`` and what it found."""

    reference: Candidate
    search: TermSearch
    proposal: Proposal | None = None  # R + D's, from every scenario
    candidates: list[Candidate] = field(default_factory=list)  # fitted with terms: R + D, and D alone
    chosen: Candidate | None = None  # the accepted one; None if no term paid its way
    folds: list[dict[str, Any]] = field(default_factory=list)  # each set's and fold's own proposal
    resembles: list[tuple[str, float]] = field(default_factory=list)  # library effects, most alike first
    margin: float = math.nan  # the BIC margin the terms had to beat (extended)
    proofs: dict[str, Proof] = field(default_factory=dict)  # each fitted candidate's, by its label
    reason: str = ""

    @property
    def terms(self) -> dict[str, float]:
        return self.search.terms_of(self.chosen.full) if self.chosen is not None else {}

    @property
    def proof(self) -> Proof | None:
        """The accepted candidate's proof (the best tried when none was accepted)."""
        best = self.chosen or min(self.candidates, key=lambda c: c.cross_validated, default=None)
        return self.proofs.get(best.label) if best is not None else None

    def to_json(self) -> dict[str, Any]:
        best = min(self.candidates, key=lambda c: c.cross_validated, default=None)
        return {
            "reference": self.reference.label,
            "held_out_reference": self.reference.cross_validated,
            "bic_reference": self.reference.bic,
            "proposed": dict(self.proposal.terms) if self.proposal else {},
            "proposed_text": self.proposal.readable() if self.proposal else [],
            "inclusion": dict(self.proposal.inclusion) if self.proposal else {},
            "folds": self.folds,
            "bic_margin": self.margin,
            "accepted": self.chosen is not None,
            "chosen": self.chosen.label if self.chosen is not None else None,
            "resembles": resemblance_words(self.resembles) if self.chosen is not None else None,
            "tried": [
                {
                    "id": c.label,
                    "terms": self.search.terms_of(c.full),
                    "text": self.search.readable(c.full.point),
                    "held_out": c.cross_validated,
                    "bic": c.bic,
                }
                for c in self.candidates
            ],
            "best_held_out": best.cross_validated if best is not None else None,
            "proof": self.proof.to_json() if self.proof is not None else None,
            "reason": self.reason,
        }


def proof_of(candidate: Candidate, folds: Sequence[Mapping[str, Any]], search: TermSearch) -> Proof:
    """A fitted candidate's proof: each fold proposed its own terms on its fitting scenarios, and those
    terms, fitted there, predicted its held-out ones (the candidate's held-out errors are theirs)."""
    return Proof(
        tuple(sorted(search.terms_of(candidate.full))),
        [tuple(sorted(f["terms"])) for f in folds if f["set"] == candidate.label],
        dict(candidate.held_out),
        search.offered,
    )


def sets_of(reference: Candidate) -> list[tuple[str, ...]]:
    """R + D, and D alone when R has effects (a term may explain what R was only a look-alike of)."""
    return [(*reference.ids, DISCOVERED)] + ([(DISCOVERED,)] if reference.ids else [])


def discover(
    f: Fitter,
    search: TermSearch,
    reference: Candidate,
    candidates: Sequence[Candidate],
    min_gain: float = explain.MIN_GAIN,
    bic_margin: float = explain.BIC_MARGIN,
    unit: str = "",
) -> Discovery:
    """The procedure of the module's docstring on top of ``reference``; ``candidates`` are the library sets
    already fitted (the calibrated model among them); ``unit``: the held-out error's, for the reason."""
    result = Discovery(reference, search)
    baseline = next((c for c in candidates if not c.ids), reference)
    parents = {
        ids: reference if library_ids(ids) == reference.ids else baseline for ids in sets_of(reference)
    }

    # The parents' residuals, full and per fold, in one sweep: every point was simulated by its fit already,
    # so the store answers most of it.
    residuals = f.evaluate([fit.point for parent in parents.values() for fit in (parent.full, *parent.folds)])

    def training(k: int) -> tuple[str, ...]:
        return f.folds[k].train

    def parent_fold(ids: tuple[str, ...], k: int) -> FitResult:
        return parents[ids].folds[k] if k < len(parents[ids].folds) else parents[ids].full

    # Every proposal, from every scenario and from each fold's fitting scenarios (so the held-out error does
    # not leak the choice of terms), then ranked on the parents' residuals, all at once.
    bounds = {
        ids: {p.name: (p.lower, p.upper) for p in f.problem("", library_ids(ids), f.scenarios).parameters}
        for ids in parents
    }
    jobs = {
        f"{'+'.join(ids)}/-1": Parent(
            parent.full, f.scenarios, search.propose(parent.full, f.scenarios, residuals), bounds[ids]
        )
        for ids, parent in parents.items()
    }
    for ids in parents:
        for k in range(len(f.folds)):
            fold = parent_fold(ids, k)
            jobs[f"{'+'.join(ids)}/{k}"] = Parent(
                fold, training(k), search.propose(fold, training(k), residuals), bounds[ids]
            )
    ranked = ranked_on_residuals(f, search, jobs, bic_margin)
    proposals = {ids: ranked[f"{'+'.join(ids)}/-1"] for ids in parents}
    result.proposal = proposals[sets_of(reference)[0]]
    sets = [ids for ids in parents if not proposals[ids].empty]
    if not sets:
        result.reason = (
            "the search supports no term"
            if all(jobs[f"{'+'.join(ids)}/-1"].proposal.empty for ids in parents)
            else "no proposed term moves the residuals enough to pay its way, linearised"
        )
        return result
    for ids in sets:
        f.say(f"discovery: proposed for {'+'.join(ids)}: " + "; ".join(proposals[ids].readable()))

    def full_problem(ids: tuple[str, ...], terms: Mapping[str, float]) -> FitProblem:
        base = f.problem("+".join(ids), library_ids(ids), f.scenarios, dict(parents[ids].full.values))
        return search.with_terms(base, terms, {}, proposals[ids].shapes)

    settled = settle(
        f,
        search,
        {"+".join(ids): (lambda terms, ids=ids: full_problem(ids, terms), proposals[ids]) for ids in sets},
        "discovery: fitting the terms",
    )
    fitted = [Candidate(ids, settled["+".join(ids)]) for ids in sets if settled["+".join(ids)] is not None]
    if not fitted:
        result.reason = f"no proposed term is {PRUNE_SE:g} standard errors from zero when fitted"
        return result
    folds, copies = _fold_problems(f, search, fitted, ranked, parent_fold, result.folds)
    # Each fold's proposal is fitted and scored as ranked: pruning inside a fold (fewer scenarios, so wider
    # cluster-robust intervals) could leave it with no term where the full fit keeps one.
    fold_fits = f.fit(list(folds.values()), "discovery: cross-validating the terms") if folds else {}
    for entry in result.folds:
        fit = fold_fits.get(f"{entry['set']}/fold{entry['fold']}")
        entry["kept"] = search.terms_of(fit) if fit is not None else {}
    f.hold_out(fitted, {**copies, **fold_fits})
    result.candidates = fitted
    result.proofs = {c.label: proof_of(c, result.folds, search) for c in fitted}
    result.margin = search.charged(bic_margin, max(len(search.terms_of(c.full)) for c in fitted))
    result.chosen = accept(
        search, fitted, reference, [*candidates, *fitted], result.proofs, min_gain, bic_margin
    )
    if result.chosen is None:
        best = min(fitted, key=lambda c: c.cross_validated)
        result.reason = (
            f"no term pays its way: held-out {reference.cross_validated:.4f}{unit} at best → "
            f"{best.cross_validated:.4f}{unit}, ΔBIC {best.bic - reference.bic:+.1f} (the rule: "
            f"{min_gain:.0%} lower held-out error and {result.margin:.1f} lower BIC, every "
            f"term {PRUNE_SE:g} standard errors from zero)"
        )
    return result


def _fold_problems(
    f: Fitter,
    search: TermSearch,
    fitted: Sequence[Candidate],
    ranked: Mapping[str, Proposal],
    parent_fold: Callable[[tuple[str, ...], int], FitResult],
    entries: list[dict[str, Any]],
) -> tuple[dict[str, FitProblem], dict[str, FitResult]]:
    """Each fitted candidate's folds: the fold's own proposal, on its fitting scenarios, started at the
    parent's fold fit and the full fit's values (each entry recorded in ``entries``); and the parent's fold
    fit for each fold that proposed nothing (what it predicts with then)."""
    problems, copies = {}, {}
    for c in fitted:
        for k in range(len(f.folds)):
            label = f"{c.label}/fold{k}"
            mine = ranked[f"{c.label}/{k}"]
            entries.append({"set": c.label, "fold": k, "terms": dict(mine.terms)})
            copies[label] = parent_fold(c.ids, k)
            if mine.empty:
                continue
            start = {**parent_fold(c.ids, k).values, **c.full.values}
            base = f.problem(label, library_ids(c.ids), f.folds[k].train, start)
            problems[label] = search.with_terms(base, dict(mine.terms), c.full.values, mine.shapes)
    return problems, copies


def pays(
    search: TermSearch,
    candidate: Candidate,
    candidates: Sequence[Candidate],
    min_gain: float,
    bic_margin: float,
) -> bool:
    """Whether a candidate with found terms beats every fitted part of itself: the parts without the terms
    by the extended BIC margin (the terms were searched for), those with them by the library's."""
    terms = len(search.terms_of(candidate.full))
    for part in explain.subsets(candidate, list(candidates)):
        margin = bic_margin if DISCOVERED in part.ids else search.charged(bic_margin, terms)
        if not explain.beats(candidate, part, min_gain, margin):
            return False
    return True


def without_terms(candidate: Candidate, candidates: Sequence[Candidate]) -> Candidate | None:
    """The fitted candidate with ``candidate``'s library effects and no found terms."""
    rest = set(library_ids(candidate.ids))
    return next((c for c in candidates if set(c.ids) == rest and c.validated), None)


def accept(
    search: TermSearch,
    fitted: Sequence[Candidate],
    reference: Candidate,
    candidates: Sequence[Candidate],
    proofs: Mapping[str, Proof],
    min_gain: float,
    bic_margin: float,
) -> Candidate | None:
    """The accepted candidate with terms, or None: cross-validated, its proof (``proofs``, by label) bearing
    the terms out against the same effects without them, beating the reference by the extended margin and
    every fitted part of itself; the lowest held-out error, fewer ids winning a tie within ``min_gain``."""

    def proven(c: Candidate) -> bool:
        without = without_terms(c, candidates)
        return c.label in proofs and (
            without is None or proofs[c.label].bears_out(without.cross_validated, min_gain)
        )

    eligible = [
        c
        for c in fitted
        if c.validated
        and math.isfinite(c.cross_validated)
        and search.standing(c.full) == search.terms_of(c.full)  # every term still stands
        and proven(c)
        and explain.beats(c, reference, min_gain, search.charged(bic_margin, len(search.terms_of(c.full))))
        and pays(search, c, candidates, min_gain, bic_margin)
    ]
    return explain.simplest_best(eligible, min_gain) if eligible else None


def similarity(change: np.ndarray, columns: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """Cosine between ``change`` and the best bounded linear combination of ``columns`` (scipy's lsq_linear):
    1 when the effect can reproduce the change, 0 when it cannot move the residuals that way at all."""
    from scipy.optimize import lsq_linear

    norm = float(np.linalg.norm(change))
    if norm == 0.0 or not np.any(columns):
        return 0.0
    scale = np.linalg.norm(columns, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    solved = lsq_linear(columns / scale, change, bounds=(lower * scale, upper * scale), method="bvls")
    fitted = columns / scale @ solved.x
    size = float(np.linalg.norm(fitted))
    return float(fitted @ change / (size * norm)) if size > 0 else 0.0


def resembles(
    f: Fitter, search: TermSearch, chosen: Candidate, effects: Mapping[str, Sequence[Any]]
) -> list[tuple[str, float]]:
    """Each library effect's cosine similarity, in residual space, to what the found terms do: the change of
    the residuals when the terms are switched off, against the best bounded linear combination of the
    effect's own columns there (one sweep of 2 + E points). ``effects``: each effect's parameters (with
    lower, upper and step). Most alike first."""
    point = dict(chosen.full.point)
    off = {**point, **{n: 0.0 for n in point if search.is_term(n)}}
    params = [(hid, p) for hid, parameters in effects.items() for p in parameters]
    probes = []
    for _, p in params:
        value = off.get(p.name, 0.0)
        step = p.step if value + p.step <= p.upper else -p.step
        probes.append({**off, p.name: value + step})
    residuals = f.evaluate([point, off, *probes])

    def stacked(pt: Point) -> np.ndarray | None:
        found = [residuals(pt, s) for s in f.scenarios]
        return None if any(r is None for r in found) else np.concatenate(found)

    with_, without = stacked(point), stacked(off)
    if with_ is None or without is None:
        return []
    change = with_ - without
    out = []
    for hid in effects:
        cols, lows, highs = [], [], []
        for (owner, p), probe in zip(params, probes):
            if owner != hid:
                continue
            moved = stacked(probe)
            delta = probe[p.name] - off.get(p.name, 0.0)
            cols.append(np.zeros_like(without) if moved is None else (moved - without) / delta)
            lows.append(p.lower - off.get(p.name, 0.0))
            highs.append(p.upper - off.get(p.name, 0.0))
        if cols:
            out.append(
                (
                    hid,
                    similarity(change, np.column_stack(cols), np.minimum(lows, 0.0), np.maximum(highs, 0.0)),
                )
            )
    return sorted(out, key=lambda item: -item[1])


def resemblance_words(similar: Sequence[tuple[str, float]]) -> str:
    """'resembles wheel_slip (0.96)', 'is partly like steering_lag (0.72)' or 'is unlike any library effect':
    a predicate, so a sentence reads "It resembles …"."""
    if not similar:
        return "was not compared with the library (a probe failed to simulate)"
    hid, value = similar[0]
    if value >= RESEMBLES:
        return f"resembles `{hid}` ({value:.2f})"
    if value >= PARTLY:
        return f"is partly like `{hid}` ({value:.2f})"
    return f"is unlike any library effect (closest: `{hid}`, {value:.2f})"
