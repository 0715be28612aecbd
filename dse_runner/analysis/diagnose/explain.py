"""Explain: which hypothesis (or small combination) the recordings support.

A candidate is a set of hypotheses fitted jointly with the calibrated
parameters. It is judged two ways:

* cross-validation across scenarios: the scenarios are split into folds
  (each fold takes every k-th run of each group); a fit on the other folds
  predicts each held-out run, and the held-out error (in the compared
  objective's units: noise floors for the signal effects, the mean
  cross-track error for field data) is what the candidate is worth on
  runs it never saw;
* the Bayesian information criterion of the fit on every run,
  n ln(SSE/n) + k ln n, which charges each added parameter.

A candidate beats a simpler one only if it lowers the held-out error by a
clear margin *and* lowers the BIC: improvement on fitted runs alone is what
an extra parameter always buys, and is no evidence of physics. A combination
is chosen only if it beats every fitted part of it: each member has to pay
its way, and (the noise rule, below) change the fit by more than the noise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...errors import DseError
from ...simulation.scenario import Scenario
from ...sweeps.fit import FitResult

MIN_GAIN = 0.05  # held-out error must fall by at least this fraction
BIC_MARGIN = 10.0  # "very strong" evidence on Kass and Raftery's scale


def folds(scenarios: list[Scenario], count: int) -> list[list[str]]:
    """Scenario names in ``count`` folds, each with every count-th run of each group."""
    ordered = sorted(scenarios, key=lambda s: (s.group, s.name))
    count = max(2, min(count, len(ordered)))
    return [[s.name for s in ordered[k::count]] for k in range(count)]


def bic_of(sse: float, n: int, k: int) -> float:
    """n ln(SSE/n) + k ln n: the fit's misfit, charged ln n for each of its k parameters."""
    n = max(n, 1)
    return n * math.log(max(sse, 1e-300) / n) + k * math.log(n) if math.isfinite(sse) else math.inf


def bic(fit: FitResult) -> float:
    return bic_of(fit.sse, fit.residual_count, len(fit.names))


def search_charge(offered: int, chosen: int, gamma: float = 1.0) -> float:
    """What choosing ``chosen`` members out of ``offered`` costs beyond the BIC: the extended BIC's
    2·γ·ln C(offered, chosen) (Chen and Chen, 2008). Why: the BIC charges a fitted parameter, not the
    search; among many candidate terms one fits the noise best by chance, and the more there are, the
    likelier, so a term found by searching P of them pays about 2·ln P more than one named beforehand."""
    if chosen <= 0 or offered <= chosen:
        return 0.0
    return (
        2.0 * gamma * (math.lgamma(offered + 1) - math.lgamma(chosen + 1) - math.lgamma(offered - chosen + 1))
    )


def fitted_rms(fit: FitResult) -> float:
    """The RMS of a fit's residuals on the runs it saw: optimistic beside held-out error, but free."""
    return math.sqrt(fit.sse / fit.residual_count) if fit.residual_count else math.inf


@dataclass
class Candidate:
    ids: tuple[str, ...]  # () is the calibrated baseline (hypothesis "none")
    full: FitResult  # fitted on every run
    folds: list[FitResult] = field(default_factory=list)
    held_out: dict[str, float] = field(
        default_factory=dict
    )  # scenario -> Equation 1 of the fit that did not see it
    charge: float = 0.0  # added to the BIC for the search that chose its members (search_charge)

    @property
    def label(self) -> str:
        return "+".join(self.ids) or "none"

    @property
    def validated(self) -> bool:
        """Whether it was cross-validated: a combination that fails the BIC
        gate is fitted on all runs only."""
        return bool(self.held_out)

    @property
    def cross_validated(self) -> float:
        return sum(self.held_out.values()) / len(self.held_out) if self.held_out else math.inf

    @property
    def bic(self) -> float:
        return bic(self.full) + self.charge


def beats(
    candidate: Candidate, reference: Candidate, min_gain: float = MIN_GAIN, bic_margin: float = BIC_MARGIN
) -> bool:
    """Whether ``candidate`` explains clearly more than ``reference`` on runs it was not fitted to."""
    return (
        candidate.cross_validated <= (1.0 - min_gain) * reference.cross_validated
        and candidate.bic <= reference.bic - bic_margin
    )


def ranked(candidates: list[Candidate]) -> list[Candidate]:
    """Best first: lowest held-out error, then lowest BIC."""
    return sorted(candidates, key=lambda c: (c.cross_validated, c.bic))


def subsets(candidate: Candidate, candidates: list[Candidate]) -> list[Candidate]:
    """The fitted candidates that are a proper part of ``candidate``, ``none`` included."""
    inside = set(candidate.ids)
    return [c for c in candidates if set(c.ids) < inside]


def beats_subsets(
    candidate: Candidate,
    candidates: list[Candidate],
    min_gain: float = MIN_GAIN,
    bic_margin: float = BIC_MARGIN,
) -> bool:
    """Whether ``candidate`` beats every fitted proper subset of it: every member pays its way. A subset
    that was not cross-validated (it failed the BIC gate) is beaten on BIC alone."""
    return all(beats(candidate, s, min_gain, bic_margin) for s in subsets(candidate, candidates))


def select(
    candidates: list[Candidate],
    baseline: Candidate,
    min_gain: float = MIN_GAIN,
    bic_margin: float = BIC_MARGIN,
) -> Candidate:
    """The answer: of the cross-validated candidates that beat ``none`` and every fitted part of
    themselves, the lowest held-out error, except that one within ``min_gain`` of it with fewer effects
    wins (no test could tell them apart, and the simpler claim is the one to make). ``baseline`` if none."""
    eligible = [
        c
        for c in candidates
        if c.ids
        and c.validated
        and beats(c, baseline, min_gain, bic_margin)
        and beats_subsets(c, candidates, min_gain, bic_margin)
    ]
    return simplest_best(eligible, min_gain) if eligible else baseline


def simplest_best(eligible: list[Candidate], min_gain: float) -> Candidate:
    """The lowest held-out error, except that one within ``min_gain`` of it with fewer effects wins: no
    test could tell them apart, and the simpler claim is the one to make."""
    best = min(eligible, key=lambda c: (c.cross_validated, c.bic))
    tied = [c for c in eligible if best.cross_validated > (1.0 - min_gain) * c.cross_validated]
    return min(tied, key=lambda c: (len(c.ids), c.cross_validated, c.bic))


def bic_gate(
    combinations: list[Candidate],
    candidates: list[Candidate],
    reference: Candidate,
    bic_margin: float,
    count: int,
) -> list[Candidate]:
    """The combinations worth cross-validating, at most ``count``, best BIC first: those whose BIC is
    ``bic_margin`` below the current answer's and below every fitted part of them. No other one could be
    chosen over the answer (the choice demands the BIC margin too), so their folds would be wasted."""
    passing = [
        c
        for c in combinations
        if c.bic <= reference.bic - bic_margin
        and all(c.bic <= s.bic - bic_margin for s in subsets(c, candidates))
    ]
    return sorted(passing, key=lambda c: c.bic)[:count]


def removal_order(chosen: Candidate, candidates: list[Candidate]) -> tuple[str, ...]:
    """The chosen effects, the one whose removal costs most first: by the held-out error of the chosen set
    without it, or by the SSE of that fit when one of them was not cross-validated. Left as they are when
    a part was never fitted."""
    if len(chosen.ids) < 2:
        return chosen.ids
    without = {}
    for hid in chosen.ids:
        rest = set(chosen.ids) - {hid}
        part = next((c for c in candidates if set(c.ids) == rest), None)
        if part is None:
            return chosen.ids
        without[hid] = part
    use_held_out = all(c.validated for c in without.values())
    return tuple(
        sorted(
            chosen.ids, key=lambda h: -(without[h].cross_validated if use_held_out else without[h].full.sse)
        )
    )


# ---- verdicts: the answer judged against the noise floor ----------------------------------------

NONE, EXPLAINED, PARTIAL, UNEXPLAINED = "none", "explained", "partial", "unexplained"
DISCOVERED = (
    "discovered"  # a data-driven correction (discover/) passed the rule and left only noise (else partial)
)
NOISE_FACTOR = 2.0  # held-out error above this many noise floors is a residual the model leaves unexplained
FLOOR_STOP = 1.25  # a fit within this many noise floors leaves nothing a combination could clearly explain
TIE = (
    1e-4  # m: held-out errors of one run closer than this are equal (an effect fitted to ~0 changes nothing)
)


def floors(value: float, option: str, default: float) -> float:
    """``value``, a count of noise floors (``--noise-factor``, a floor stop) as the user gave it under the
    name ``option``: a positive number, or an error that names it and the default."""
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise DseError(
            f"{option} {value!r}: must be a positive number of noise floors (default {default:g}; held-out "
            f"error above {NOISE_FACTOR:g} floors is a residual)"
        )
    return float(value)


def above_floor(held_out: float, floor: float | None, factor: float = NOISE_FACTOR) -> bool:
    """Whether ``held_out`` error stays clearly above what noise alone gives. Without a floor
    (none could be estimated) nothing counts as above: the verdict then claims no more than today."""
    return floor is not None and math.isfinite(floor) and floor > 0 and held_out > factor * floor


def verdict(
    held_out: float, floor: float | None, factor: float, chosen: bool, discovered: bool = False
) -> str:
    """The diagnosis in one word. ``chosen``: whether any library effect was chosen; ``discovered``: whether
    a correction inside the model was accepted (a term in its equations, or the Robotti's discovered block).

    none: nothing chosen, and the residual is noise; explained: effects chosen, and what remains is
    noise; discovered: a discovered correction brings what remains down to the noise; partial: effects
    chosen (library or discovered), yet a residual well above the noise remains, so they are at most
    part of the cause; unexplained: nothing chosen, and the residual is well above the noise."""
    above = above_floor(held_out, floor, factor)
    if discovered:
        return PARTIAL if above else DISCOVERED
    if chosen:
        return PARTIAL if above else EXPLAINED
    return UNEXPLAINED if above else NONE


def unless_white(verdict: str, white: bool) -> str:
    """The verdict once the residuals' whiteness is known: an error as small as the noise but not white is not
    indistinguishable from it (something is still missing, or the noise is coloured and its floor reads low),
    so it explains nothing for sure."""
    if white:
        return verdict
    return {EXPLAINED: PARTIAL, DISCOVERED: PARTIAL, NONE: UNEXPLAINED}.get(verdict, verdict)


def runner_up(chosen: Candidate, candidates: list[Candidate]) -> Candidate | None:
    """The best-ranked real alternative: cross-validated, not the chosen set and not a subset of it (a
    subset is the chosen answer with less in it, not a different explanation)."""
    inside = set(chosen.ids)
    return next((c for c in ranked(candidates) if c.validated and not set(c.ids) <= inside), None)


@dataclass(frozen=True)
class Evidence:
    """Why the chosen candidate and not ``other``: each Δ is other minus chosen, so positive favours the
    chosen one. ``runs_better`` counts the held-out runs the chosen model predicts better by more than
    ``TIE``, ``runs_tied`` those the two predict equally well.

    ΔBIC counts every fix as independent; fixes within a run are strongly correlated, so it
    overstates the evidence. Held-out Δ and runs_better are the figures to quote."""

    other: str
    other_held_out: float
    delta_bic: float
    delta_held_out: float  # in the held-out error's units
    delta_held_out_percent: float  # of the chosen candidate's held-out error
    runs_better: int
    runs: int
    runs_tied: int = 0

    @property
    def runs_better_text(self) -> str:
        return f"{self.runs_better}/{self.runs}"

    def to_json(self) -> dict[str, object]:
        return {
            "id": self.other,
            "held_out": self.other_held_out,
            "delta_bic": self.delta_bic,
            "delta_held_out": self.delta_held_out,
            "delta_held_out_percent": self.delta_held_out_percent,
            "runs_better": self.runs_better_text,
            "runs_tied": self.runs_tied,
        }


def evidence(chosen: Candidate, other: Candidate) -> Evidence:
    """The evidence for ``chosen`` over ``other`` from their fits and held-out errors."""
    runs = sorted(set(chosen.held_out) & set(other.held_out))
    delta = other.cross_validated - chosen.cross_validated
    base = chosen.cross_validated
    percent = 100.0 * delta / base if math.isfinite(delta) and base > 0 and math.isfinite(base) else math.nan
    margins = [other.held_out[s] - chosen.held_out[s] for s in runs]
    return Evidence(
        other.label,
        other.cross_validated,
        other.bic - chosen.bic,
        delta,
        percent,
        sum(m > TIE for m in margins),
        len(runs),
        sum(abs(m) <= TIE for m in margins),
    )


# ---- the noise rule ------------------------------------------------------------------------------
# Held-out error and the BIC choose among candidates, but a member of a combination can pass both by a
# whisker while changing the prediction by far less than the recordings' own noise (on a held-back
# Robotti set a terrain slope of grade 4e-5 was named beside the right effect). Taking a member out of
# the chosen set raises the held-out mean square by what it changes the prediction by, squared: a member
# whose removal adds less than one noise variance (NOISE_RULE) is not claimed.

NOISE_RULE = 1.0  # noise variances a claimed member must add to the held-out mean square when removed


def mean_square(candidate: Candidate, unit: float = 1.0) -> float:
    """The held-out mean square in noise variances (``unit``: the error the noise alone makes, in the
    held-out error's units), over the runs the candidate was judged on."""
    values = [(v / unit) ** 2 for v in candidate.held_out.values()]
    return float(np.mean(values)) if values else math.inf


def worth(
    member: str, chosen: Candidate, candidates: Sequence[Candidate], baseline: Candidate, unit: float = 1.0
) -> float:
    """What removing ``member`` from ``chosen`` adds to the held-out mean square, in noise variances; inf
    when the set without it was never cross-validated (it could not be judged, so it is kept)."""
    rest = set(chosen.ids) - {member}
    without = (
        baseline if not rest else next((c for c in candidates if set(c.ids) == rest and c.validated), None)
    )
    if without is None or not without.validated:
        return math.inf
    return mean_square(without, unit) - mean_square(chosen, unit)


@dataclass(frozen=True)
class Dropped:
    """An effect the choice had named but a rule took away: the noise rule (removing it added ``worth`` noise
    variances, below ``NOISE_RULE``, to the held-out mean square), or another rule that gives its
    ``reason`` (a limit the recordings never reach, terms their proof did not bear out)."""

    id: str
    worth: float
    reason: str = ""  # another rule's (a limit the recordings never reach), when not the noise rule

    def to_json(self) -> dict[str, Any]:
        rule = self.reason or f"removal adds < {NOISE_RULE:g} noise variance to the held-out mean square"
        return {"id": self.id, "worth": self.worth, "rule": rule}


def claimed(
    chosen: Candidate,
    candidates: Sequence[Candidate],
    baseline: Candidate,
    unit: float = 1.0,
    rule: float = NOISE_RULE,
) -> tuple[Candidate, list[Dropped]]:
    """``chosen`` without every member whose removal changes the held-out error by less than the noise,
    the least worthy first, each time judged again on what is left. ``unit``: the held-out error the
    noise alone makes (1 where residuals are already in noise floors)."""
    dropped: list[Dropped] = []
    while chosen.ids:
        worths = {m: worth(m, chosen, candidates, baseline, unit) for m in chosen.ids}
        member = min(worths, key=worths.__getitem__)
        if worths[member] >= rule:
            break
        dropped.append(Dropped(member, worths[member]))
        rest = set(chosen.ids) - {member}
        chosen = baseline if not rest else next(c for c in candidates if set(c.ids) == rest and c.validated)
    return chosen, dropped
