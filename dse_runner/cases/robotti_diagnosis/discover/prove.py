"""Discovery, stage 3: prove the ranked terms with the same fits, folds and rule as the library, and accept or
reject them."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from ....analysis.diagnose import explain
from ....analysis.diagnose.explain import Candidate
from ....analysis.diagnose.proof import Proof
from ....analysis.diagnose.sparse_regression import PRUNE_SE
from ....analysis.diagnose.sparse_regression import pruned as generic_pruned
from ....sweeps.fit import FitProblem, FitResult
from .. import correction
from .observe import Observed, vehicle_values
from .propose import CorrectionProposal, propose, regressions
from .rank_terms import (
    DISCOVERED,
    Fitter,
    Screen,
    charged,
    held_shapes,
    library_ids,
    screened,
    searched_count,
)
from .resemble import resemblance_words


def with_terms(
    problem: FitProblem,
    vehicle: str,
    terms: Mapping[str, float],
    start: Mapping[str, float],
    rms: Mapping[str, float],
    shapes: Mapping[str, float] = {},
) -> FitProblem:
    """``problem`` with the correction terms freed: each bounded by correction.bound over the runs' feature
    RMS, starting from ``start`` (a fitted point) where it has the term, else from the proposal; the shapes
    the terms depend on held at their values in ``shapes``."""
    extra = []
    for variable, value in terms.items():
        name = f"{vehicle}.{variable}"
        extra.append(
            correction.parameter(
                correction.term(variable), vehicle, rms.get(variable), start.get(name, value)
            )
        )
    names = {p.name for p in extra}
    held = held_shapes(shapes, vehicle, list(terms))
    return replace(
        problem,
        parameters=problem.parameters + tuple(extra),
        fixed={**{k: v for k, v in problem.fixed.items() if k not in names}, **held},
    )


def fitted_terms(fit: FitResult) -> dict[str, float]:
    """The correction terms a fit moved, local names -> values."""
    return {n.rsplit(".", 1)[-1]: v for n, v in fit.values.items() if correction.is_correction(n)}


def pruned(fit: FitResult, factor: float = PRUNE_SE) -> dict[str, float]:
    """The fitted correction terms at least ``factor`` cluster-robust standard errors from zero (an
    undetermined one is dropped; sparse_regression.pruned), local names -> values."""
    kept = generic_pruned(fit, [n for n in fit.values if correction.is_correction(n)], factor)
    return {name.rsplit(".", 1)[-1]: fit.values[name] for name in kept}


def refilled(
    kept: Mapping[str, float], proposal: CorrectionProposal, tried: set[str], max_terms: int
) -> dict[str, float]:
    """The kept terms (at zero: the dropped ones may have balanced them) and, in the slots pruning freed, the
    next terms the proposal ranked that were not tried yet (at their proposed values). Equation error sees
    more than dynamics (the model's own misfit shows in it too), so a term it ranks high may fall on
    positions; the slot is then the next term's, not lost."""
    out = {v: 0.0 for v in kept}
    for variable, value in proposal.ranked:
        if len(out) >= max_terms:
            break
        if variable not in out and variable not in tried:
            out[variable] = value
    return out


def settle(
    chain: Fitter,
    jobs: Mapping[str, tuple[Callable[[Mapping[str, float]], FitProblem], CorrectionProposal]],
    what: str,
) -> dict[str, FitResult | None]:
    """Fit each job's proposed terms, prune those within PRUNE_SE standard errors of zero, refit with the
    freed slots refilled (:func:`refilled`; all of them when no term survived), then prune and refit
    without refilling until every term stands; lockstep batches throughout. ``jobs``: label -> (problem
    for given terms, proposal). None where no term survives."""
    max_terms = chain.settings.max_terms
    fits = chain.fit([make(dict(proposal.terms)) for make, proposal in jobs.values()], what)
    tried = {label: set(proposal.terms) for label, (_, proposal) in jobs.items()}
    out: dict[str, FitResult | None] = {}
    for refill in (True, *[False] * max_terms):  # without refilling each pass drops a term: it ends
        again = []
        for label, (make, proposal) in jobs.items():
            if label in out:
                continue
            fit = fits[label]
            kept = pruned(fit)
            if kept == fitted_terms(fit):
                continue  # settled: every term two standard errors from zero
            terms = refilled(kept, proposal, tried[label], max_terms) if refill else {v: 0.0 for v in kept}
            if not terms:
                out[label] = None  # nothing survived, and nothing is left to try
                continue
            tried[label] |= set(terms)
            again.append(make(terms))
        if not again:
            break
        fits.update(chain.fit(again, f"{what}: refitting without the terms near zero"))
    return {label: out.get(label, fits[label]) for label in jobs}


@dataclass
class Discovery:
    """What discovery tried on top of ``reference`` and what it found."""

    reference: Candidate
    proposal: CorrectionProposal | None = None  # from every run
    candidates: list[Candidate] = field(default_factory=list)  # fitted with terms: R + D, and D alone
    chosen: Candidate | None = None  # the accepted one; None if no term paid its way
    folds: list[dict[str, Any]] = field(default_factory=list)  # each set's and fold's own proposal
    resembles: list[tuple[str, float]] = field(
        default_factory=list
    )  # library effects by similarity, best first
    margin: float = math.nan  # the BIC margin the terms had to beat (extended)
    proofs: dict[str, Proof] = field(default_factory=dict)  # each fitted candidate's, by its label
    reason: str = ""

    @property
    def terms(self) -> dict[str, float]:
        return fitted_terms(self.chosen.full) if self.chosen is not None else {}

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
                    "terms": fitted_terms(c.full),
                    "text": correction.readable(c.full.point),
                    "held_out": c.cross_validated,
                    "bic": c.bic,
                }
                for c in self.candidates
            ],
            "best_held_out": best.cross_validated if best is not None else None,
            "proof": self.proof.to_json() if self.proof is not None else None,
            "reason": self.reason,
        }


def proof_of(candidate: Candidate, folds: Sequence[Mapping[str, Any]]) -> Proof:
    """A fitted candidate's proof: each fold proposed and ranked its own terms on its training runs, and
    those terms, fitted there, predicted its held-out runs (the candidate's held-out errors are theirs)."""
    return Proof(
        tuple(sorted(fitted_terms(candidate.full))),
        [tuple(sorted(f["terms"])) for f in folds if f["set"] == candidate.label],
        dict(candidate.held_out),
        searched_count(),
    )


def _sets(reference: Candidate) -> list[tuple[str, ...]]:
    """R + D, and D alone when R has effects (a term may explain what R was only a look-alike of)."""
    return [(*reference.ids, DISCOVERED)] + ([(DISCOVERED,)] if reference.ids else [])


def discover(
    chain: Fitter,
    reference: Candidate,
    candidates: Sequence[Candidate],
    runs: Sequence[Observed],
    fixed: Mapping[str, Any] = {},
) -> Discovery:
    """Propose terms on top of ``reference`` (R + D) and of the calibrated model alone (D alone, when R has
    effects: a term may explain what R only looked like), each from every run; fit them on every run and
    prune them; re-propose and fit inside each fold on its training runs; score the held-out runs; accept by
    the library's rule with the extended BIC margin. ``candidates`` are the library sets already fitted."""
    settings, vehicle = chain.settings, chain.vehicle
    result = Discovery(reference)
    by_name = {r.name: r for r in runs}
    baseline = next((c for c in candidates if not c.ids), reference)
    parents = {ids: reference if library_ids(ids) == reference.ids else baseline for ids in _sets(reference)}

    # The parents' fix residuals (the antenna channels' targets), full and per fold, in one sweep: every
    # point was simulated by its fit already, so the store answers most of it.
    points = [f.point for parent in parents.values() for f in (parent.full, *parent.folds)]
    residuals = chain.evaluate(points)

    def proposal(parent: FitResult, names: Sequence[str]) -> CorrectionProposal:
        values = vehicle_values(parent.point, vehicle, fixed)
        mine = [by_name[n] for n in names if n in by_name]
        return propose(
            regressions(mine, values, {r.name: residuals(parent.point, r.name) for r in mine}),
            settings.max_terms,
        )

    def training(k: int) -> tuple[str, ...]:
        return chain.folds[k].train

    def parent_fold(ids: tuple[str, ...], k: int) -> FitResult:
        return parents[ids].folds[k] if k < len(parents[ids].folds) else parents[ids].full

    # Every proposal, from every run and from each fold's training runs (so the held-out error does not
    # leak the choice of terms), then ranked on positions at its parent, all in one sweep.
    raw = {ids: proposal(parent.full, chain.scenarios) for ids, parent in parents.items()}
    rms = {k: v for p in raw.values() for k, v in p.rms.items()}
    bounds = {
        ids: {
            p.name: (p.lower, p.upper)
            for p in chain.problem("", library_ids(ids), chain.scenarios).parameters
        }
        for ids in parents
    }
    jobs_ = {
        ("+".join(ids), -1): Screen(parent.full, chain.scenarios, raw[ids], bounds[ids])
        for ids, parent in parents.items()
    }
    for ids in parents:
        for k in range(len(chain.folds)):
            fold_proposal = proposal(parent_fold(ids, k), training(k))
            rms.update({v: x for v, x in fold_proposal.rms.items() if v not in rms})
            jobs_[("+".join(ids), k)] = Screen(parent_fold(ids, k), training(k), fold_proposal, bounds[ids])
    ranked = screened(chain, {f"{a}/{k}": job for (a, k), job in jobs_.items()}, rms)
    proposals = {ids: ranked[f"{'+'.join(ids)}/-1"] for ids in parents}
    result.proposal = proposals[_sets(reference)[0]]
    sets = [ids for ids in parents if not proposals[ids].empty]
    if not sets:
        result.reason = (
            "the equation error supports no term"
            if all(p.empty for p in raw.values())
            else "no proposed term moves the fix residuals enough to pay its way, linearised"
        )
        return result
    for ids in sets:
        chain.say(f"discovery: proposed for {'+'.join(ids)}: " + "; ".join(proposals[ids].readable()))

    def full_problem(ids: tuple[str, ...], terms: Mapping[str, float]) -> FitProblem:
        base = chain.problem("+".join(ids), library_ids(ids), chain.scenarios, dict(parents[ids].full.values))
        return with_terms(base, vehicle, terms, {}, rms, proposals[ids].shapes)

    settled = settle(
        chain,
        {"+".join(ids): (lambda terms, ids=ids: full_problem(ids, terms), proposals[ids]) for ids in sets},
        "discovery: fitting the correction",
    )
    fitted = [Candidate(ids, settled["+".join(ids)]) for ids in sets if settled["+".join(ids)] is not None]
    if not fitted:
        result.reason = "no proposed term is two standard errors from zero when fitted on positions"
        return result
    jobs, copies = {}, {}
    for c in (
        fitted
    ):  # fold-honest: each fold's own proposal, on its training runs, ranked at its parent's fold fit
        for k in range(len(chain.folds)):
            label = f"{c.label}/fold{k}"
            mine = ranked[f"{c.label}/{k}"]
            result.folds.append({"set": c.label, "fold": k, "terms": mine.terms})
            copies[label] = parent_fold(c.ids, k)  # what the fold predicts with when no term is proposed
            if mine.empty:
                continue

            def make(
                terms: Mapping[str, float],
                label: str = label,
                c: Candidate = c,
                k: int = k,
                shapes: Mapping[str, float] = mine.shapes,
            ) -> FitProblem:
                base = chain.problem(
                    label, library_ids(c.ids), training(k), {**parent_fold(c.ids, k).values, **c.full.values}
                )
                return with_terms(base, vehicle, terms, c.full.values, rms, shapes)

            jobs[label] = (make, mine)
    # Each fold's proposal is fitted and scored as ranked: the ranking on positions already leaves out the
    # terms that would only stand in for others, and pruning inside a fold (fewer runs, so wider
    # cluster-robust intervals) can leave it with no term where the full fit keeps one.
    fold_fits = (
        chain.fit(
            [make(dict(mine.terms)) for make, mine in jobs.values()],
            "discovery: cross-validating the correction",
        )
        if jobs
        else {}
    )
    for entry in result.folds:
        fit = fold_fits.get(f"{entry['set']}/fold{entry['fold']}")
        entry["kept"] = fitted_terms(fit) if fit is not None else {}
    chain.hold_out(fitted, {**copies, **fold_fits})
    result.candidates = fitted
    result.proofs = {c.label: proof_of(c, result.folds) for c in fitted}
    result.margin = charged(settings.bic_margin, max(len(fitted_terms(c.full)) for c in fitted))
    result.chosen = accept(
        fitted, reference, [*candidates, *fitted], result.proofs, settings.min_gain, settings.bic_margin
    )
    if result.chosen is None:
        best = min(fitted, key=lambda c: c.cross_validated)
        result.reason = (
            f"no correction pays its way: held-out {reference.cross_validated:.4f} m at best → "
            f"{best.cross_validated:.4f} m, ΔBIC {best.bic - reference.bic:+.1f} (the rule: "
            f"{settings.min_gain:.0%} lower held-out error and {result.margin:.1f} lower BIC, every "
            "term two standard errors from zero)"
        )
    return result


def pays(candidate: Candidate, candidates: Sequence[Candidate], min_gain: float, bic_margin: float) -> bool:
    """Whether a candidate with discovered terms beats every fitted part of itself: the parts without the
    terms by the extended BIC margin (the terms were searched for), those with them by the library's."""
    terms = len(fitted_terms(candidate.full))
    for part in explain.subsets(candidate, list(candidates)):
        margin = bic_margin if DISCOVERED in part.ids else charged(bic_margin, terms)
        if not explain.beats(candidate, part, min_gain, margin):
            return False
    return True


def without_terms(candidate: Candidate, candidates: Sequence[Candidate]) -> Candidate | None:
    """The fitted candidate with ``candidate``'s library effects and no discovered terms."""
    rest = set(library_ids(candidate.ids))
    return next((c for c in candidates if set(c.ids) == rest and c.validated), None)


def accept(
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
        and pruned(c.full) == fitted_terms(c.full)  # every term still two standard errors from zero
        and proven(c)
        and explain.beats(c, reference, min_gain, charged(bic_margin, len(fitted_terms(c.full))))
        and pays(c, candidates, min_gain, bic_margin)
    ]
    return explain.simplest_best(eligible, min_gain) if eligible else None
