"""Explain: which hypothesis (or small combination) the recordings support.

A candidate is a set of hypotheses fitted jointly with the calibrated
parameters. It is judged two ways:

* cross-validation across scenarios: the scenarios are split into folds
  (each fold takes every k-th run of each group); a fit on the other folds
  predicts each held-out run, and the held-out mean cross-track error
  (Equation 1) is what the candidate is worth on runs it never saw;
* the Bayesian information criterion of the fit on every run,
  n ln(SSE/n) + k ln n, which charges each added parameter.

A candidate beats a simpler one only if it lowers the held-out error by a
clear margin *and* lowers the BIC: improvement on fitted runs alone is what
an extra parameter always buys, and is no evidence of physics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ...simulation.scenario import Scenario
from ...sweeps.fit import FitResult

MIN_GAIN = 0.05  # held-out error must fall by at least this fraction
BIC_MARGIN = 10.0  # "very strong" evidence on Kass and Raftery's scale


def folds(scenarios: list[Scenario], count: int) -> list[list[str]]:
    """Scenario names in ``count`` folds, each with every count-th run of each group."""
    ordered = sorted(scenarios, key=lambda s: (s.group, s.name))
    count = max(2, min(count, len(ordered)))
    return [[s.name for s in ordered[k::count]] for k in range(count)]


def bic(fit: FitResult) -> float:
    n = max(fit.residual_count, 1)
    return n * math.log(max(fit.sse, 1e-300) / n) + len(fit.names) * math.log(n)


@dataclass
class Candidate:
    ids: tuple[str, ...]  # () is the calibrated baseline (hypothesis "none")
    full: FitResult  # fitted on every run
    folds: list[FitResult] = field(default_factory=list)
    held_out: dict[str, float] = field(default_factory=dict)  # scenario -> Equation 1 of the fit that did not see it

    @property
    def label(self) -> str:
        return "+".join(self.ids) or "none"

    @property
    def cross_validated(self) -> float:
        return sum(self.held_out.values()) / len(self.held_out) if self.held_out else math.inf

    @property
    def bic(self) -> float:
        return bic(self.full)


def beats(candidate: Candidate, reference: Candidate, min_gain: float = MIN_GAIN,
          bic_margin: float = BIC_MARGIN) -> bool:
    """Whether ``candidate`` explains clearly more than ``reference`` on runs it was not fitted to."""
    return (candidate.cross_validated <= (1.0 - min_gain) * reference.cross_validated
            and candidate.bic <= reference.bic - bic_margin)


def ranked(candidates: list[Candidate]) -> list[Candidate]:
    """Best first: lowest held-out error, then lowest BIC."""
    return sorted(candidates, key=lambda c: (c.cross_validated, c.bic))


# ---- verdicts: the answer judged against the noise floor ----------------------------------------

NONE, EXPLAINED, PARTIAL, UNEXPLAINED = "none", "explained", "partial", "unexplained"
NOISE_FACTOR = 2.0  # held-out error above this many noise floors is a residual the model leaves unexplained
TIE = 1e-4  # m: held-out errors of one run closer than this are equal (an effect fitted to ~0 changes nothing)


def above_floor(held_out: float, floor: float | None, factor: float = NOISE_FACTOR) -> bool:
    """Whether ``held_out`` error stays clearly above what noise alone gives. Without a floor
    (none could be estimated) nothing counts as above: the verdict then claims no more than today."""
    return floor is not None and math.isfinite(floor) and floor > 0 and held_out > factor * floor


def verdict(held_out: float, floor: float | None, factor: float, chosen: bool) -> str:
    """The diagnosis in one word. ``chosen``: whether any library effect was chosen.

    none: nothing chosen, and the residual is noise; explained: effects chosen, and what remains is
    noise; partial: effects chosen, yet a residual well above the noise remains, so they are at most
    part of the cause; unexplained: nothing chosen, and the residual is well above the noise."""
    above = above_floor(held_out, floor, factor)
    if chosen:
        return PARTIAL if above else EXPLAINED
    return UNEXPLAINED if above else NONE


def runner_up(chosen: Candidate, candidates: list[Candidate]) -> Candidate | None:
    """The best-ranked real alternative: not the chosen set and not a subset of it (a subset is the
    chosen answer with less in it, not a different explanation)."""
    inside = set(chosen.ids)
    return next((c for c in ranked(candidates) if not set(c.ids) <= inside), None)


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
    delta_held_out: float  # m
    delta_held_out_percent: float  # of the chosen candidate's held-out error
    runs_better: int
    runs: int
    runs_tied: int = 0

    @property
    def runs_better_text(self) -> str:
        return f"{self.runs_better}/{self.runs}"

    def to_json(self) -> dict[str, object]:
        return {"id": self.other, "cross_track_held_out": self.other_held_out, "delta_bic": self.delta_bic,
                "delta_held_out": self.delta_held_out, "delta_held_out_percent": self.delta_held_out_percent,
                "runs_better": self.runs_better_text, "runs_tied": self.runs_tied}


def evidence(chosen: Candidate, other: Candidate) -> Evidence:
    """The evidence for ``chosen`` over ``other`` from their fits and held-out errors."""
    runs = sorted(set(chosen.held_out) & set(other.held_out))
    delta = other.cross_validated - chosen.cross_validated
    base = chosen.cross_validated
    percent = 100.0 * delta / base if math.isfinite(delta) and base > 0 and math.isfinite(base) else math.nan
    margins = [other.held_out[s] - chosen.held_out[s] for s in runs]
    return Evidence(other.label, other.cross_validated, other.bic - chosen.bic, delta, percent,
                    sum(m > TIE for m in margins), len(runs), sum(abs(m) <= TIE for m in margins))
