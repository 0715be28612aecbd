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
