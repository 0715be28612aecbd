"""Look-alikes: telling twin explanations apart by where their fits differ, not by the luck of the draw.

Some effects leave nearly the same residual on ordinary data, so held-out error and BIC differ by little,
and whichever wins does so by the noise. Both twins are fitted on every run anyway, and their residuals
are the evidence between them: the log-likelihood ratio of Gaussian noise of σ,

    LLR = Σ (r_b² − r_a²) / (2 σ²) / τ       (positive favours a)

summed per *segment kind* (what the inputs did there), with τ the residuals' integrated autocorrelation
time in samples: successive samples of a smooth residual are not independent pieces of evidence, and
counting them as such would overstate the ratio by τ. When held-out error and BIC cannot separate two
twins and |ΣLLR| ≥ ``DECISIVE``, the ratio decides; below it the diagnosis names both.

The engine owns the statistics and the rule, and which sets are twins when a library declares its
look-alikes (:func:`swaps`: one member swapped for a declared twin; the screen shortlists them, and
:func:`twin_pairs` says which fitted ones to weigh). A library supplies what it alone knows
(:class:`Segments`): how a candidate's residuals fall into samples (a position's two coordinates add into
one sample) and which segment each sample lies in. The labels only say *where* the evidence lies: the
total, and so the decision, does not depend on them. How each twin answers a command (a delay, a lag, a
gain) is response.py's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from . import explain
from .explain import Candidate

DECISIVE = 5.0  # |Σ LLR| at which the evidence between twins decides (e^5 ≈ 150 : 1)
MAX_LAG = 200  # samples: the autocorrelation sum stops here at the latest
DECIDED_BY_FIT, DECIDED_BY_LLR, CANNOT_TELL = "held_out", "llr", "cannot_tell"
UNLABELLED = "unlabelled"  # a sample outside every segment

Piece = tuple[np.ndarray, np.ndarray]  # (components × samples residuals, one segment label per sample)


@dataclass(frozen=True)
class Segments:
    """What a library supplies for the evidence between twins. ``pieces`` lays a candidate's residuals
    out as pieces (a run, or one signal of a run), each a 2-D array whose rows are the components that
    add into one sample's squared residual (one row for a plain signal; two for a position's x and y) and
    whose columns are the samples, with a segment label per sample; None when that candidate's residuals
    cannot be laid out (fitted on other runs). ``kinds``: the order to report the segment kinds in;
    ``sample``: what one sample is called (the JSON's ``autocorrelation_<sample>``)."""

    pieces: Callable[[Candidate], list[Piece] | None]
    kinds: tuple[str, ...] = ()
    sample: str = "samples"


def autocorrelation_time(series: Sequence[np.ndarray], max_lag: int = MAX_LAG) -> float:
    """1 + 2 Σ ρ_k, the integrated autocorrelation time (in samples) of the pooled series, each about its
    mean, the sum stopped at the first ρ_k ≤ 0 (Geyer's initial positive sequence, simplified). White
    noise gives 1; AR(1) noise of lag-1 correlation ρ gives (1 + ρ)/(1 − ρ); a residual that wanders slowly,
    the number of samples it takes to forget itself."""
    parts = [np.asarray(s, float) - np.mean(s) for s in series if len(s) > 2]
    if not parts:
        return 1.0
    variance = sum(float(p @ p) for p in parts)
    if variance <= 0:
        return 1.0
    tau = 1.0
    for k in range(1, min(max_lag, max(len(p) for p in parts) - 1) + 1):
        rho = sum(float(p[k:] @ p[:-k]) for p in parts if len(p) > k) / variance
        if rho <= 0:
            break
        tau += 2.0 * rho
    return tau


@dataclass(frozen=True)
class SegmentEvidence:
    """Σ LLR of set a over set b (positive favours a), in total and per segment kind, with the samples per
    kind, the autocorrelation time τ [samples] and the noise σ it was scaled by."""

    llr: float
    by_kind: dict[str, float]
    samples: dict[str, int]
    tau: float
    sigma: float


def segment_evidence(
    a: Sequence[Piece], b: Sequence[Piece], sigma: float, kinds: Sequence[str] = ()
) -> SegmentEvidence:
    """The evidence for residuals ``a`` over ``b``, laid out alike (:class:`Segments`; ``b``'s labels are
    ``a``'s). τ comes from the better set's residuals, each component a series of its own: under the right
    model they are the noise, and how correlated that noise is sets how many independent samples there
    are. ``kinds``: the order of the kinds in the result (others follow, sorted)."""
    per_a = [np.sum(np.atleast_2d(r) ** 2, axis=0) for r, _ in a]
    per_b = [np.sum(np.atleast_2d(r) ** 2, axis=0) for r, _ in b]
    better = a if sum(map(np.sum, per_a)) <= sum(map(np.sum, per_b)) else b
    tau = autocorrelation_time([row for r, _ in better for row in np.atleast_2d(r)])
    by_kind: dict[str, float] = {}
    samples: dict[str, int] = {}
    for fa, fb, (_, labels) in zip(per_a, per_b, a):
        contribution = (fb - fa) / (2.0 * sigma**2 * tau)
        for kind in np.unique(labels):
            inside = labels == kind
            name = str(kind) or UNLABELLED
            by_kind[name] = by_kind.get(name, 0.0) + float(contribution[inside].sum())
            samples[name] = samples.get(name, 0) + int(inside.sum())
    ordered = [k for k in (*kinds, UNLABELLED) if k in by_kind]
    ordered += sorted(k for k in by_kind if k not in ordered)
    return SegmentEvidence(
        float(sum(by_kind.values())),
        {k: by_kind[k] for k in ordered},
        {k: samples[k] for k in ordered},
        tau,
        sigma,
    )


def decision(
    a: Candidate,
    b: Candidate,
    llr: float,
    min_gain: float = explain.MIN_GAIN,
    bic_margin: float = explain.BIC_MARGIN,
    decisive: float = DECISIVE,
) -> str:
    """held_out when held-out error and BIC already separate the two (one beats the other); else llr when
    |llr| ≥ ``decisive``; else cannot_tell."""
    if (
        a.validated
        and b.validated
        and (explain.beats(a, b, min_gain, bic_margin) or explain.beats(b, a, min_gain, bic_margin))
    ):
        return DECIDED_BY_FIT
    return DECIDED_BY_LLR if abs(llr) >= decisive else CANNOT_TELL


def eligible(
    candidate: Candidate,
    candidates: Sequence[Candidate],
    baseline: Candidate,
    min_gain: float,
    bic_margin: float,
) -> bool:
    """Whether ``candidate`` could be the answer (explain.select's rule): cross-validated, better than none
    and than every fitted part of it."""
    return (
        candidate.validated
        and explain.beats(candidate, baseline, min_gain, bic_margin)
        and explain.beats_subsets(candidate, candidates, min_gain, bic_margin)
    )


@dataclass
class Twins:
    """The evidence between two twin sets: ``pair`` = (first, second) labels, ``members`` what is swapped
    between them (each side's own members), ``evidence`` for the first over the second. ``decision`` is how
    they were told apart: by held-out error and BIC, by the LLR, or not at all (``cannot_tell``); ``chosen``
    the label the diagnosis answers with (None when nothing is chosen)."""

    pair: tuple[str, str]
    members: tuple[str, str]
    evidence: SegmentEvidence
    decision: str
    chosen: str | None
    sample: ClassVar[str] = "samples"  # what one sample is called in the JSON

    @property
    def favoured(self) -> str:
        return self.pair[0] if self.evidence.llr >= 0 else self.pair[1]

    def to_json(self) -> dict[str, Any]:
        e = self.evidence
        return {
            "pair": list(self.pair),
            "effects": list(self.members),
            "chosen": self.chosen,
            "llr": e.llr,
            "favours": self.favoured,
            "decision": self.decision,
            "by_segment": {k: {"llr": v, self.sample: e.samples[k]} for k, v in e.by_kind.items()},
            f"autocorrelation_{self.sample}": e.tau,
            "sigma": e.sigma,
        }


def swaps(
    ids: Sequence[str], look_alikes: Mapping[str, Sequence[str]]
) -> dict[frozenset[str], tuple[str, str]]:
    """The twins of set ``ids``: each set that is ``ids`` with one member x replaced by y, a declared
    look-alike of x not already in it (``look_alikes``: id -> its twins), with (x, y), in ``ids``' order.
    The screen shortlists them beside the sets it chose (screens.base); :func:`twin_pairs` weighs them."""
    return {
        frozenset(set(ids) - {x} | {y}): (x, y) for x in ids for y in look_alikes.get(x, ()) if y not in ids
    }


def swapped(
    a: Sequence[str], b: Sequence[str], look_alikes: Mapping[str, Sequence[str]]
) -> tuple[str, str] | None:
    """(x, y) when set ``b`` is one of :func:`swaps` of set ``a``: its member x replaced by y; else None."""
    return swaps(a, look_alikes).get(frozenset(b))


def twin_pairs(
    chosen: Candidate, candidates: Sequence[Candidate], look_alikes: Mapping[str, Sequence[str]]
) -> list[tuple[Candidate, Candidate]]:
    """The pairs to weigh when a library declares its look-alikes: the chosen set against each fitted set
    that swaps one of its members for a look-alike (:func:`swapped`); when nothing is chosen, the two
    best-ranked cross-validated sets if they are twins."""
    fitted = [c for c in candidates if c.full.residuals]
    if chosen.ids:
        return [(chosen, c) for c in fitted if swapped(chosen.ids, c.ids, look_alikes)]
    top = [c for c in explain.ranked(fitted) if c.ids and c.validated][:2]
    return [(top[0], top[1])] if len(top) == 2 and swapped(top[0].ids, top[1].ids, look_alikes) else []


def members(a: Candidate, b: Candidate) -> tuple[str, str]:
    """What each of two sets has that the other lacks, each side joined by +."""
    return "+".join(i for i in a.ids if i not in b.ids), "+".join(i for i in b.ids if i not in a.ids)


def weighed(
    a: Candidate,
    b: Candidate,
    segments: Segments,
    sigma: float | None,
    min_gain: float = explain.MIN_GAIN,
    bic_margin: float = explain.BIC_MARGIN,
) -> Twins | None:
    """The evidence between ``a`` and ``b`` and how it decides; None when their residuals cannot be laid
    out alike. ``sigma``: the noise per component; without it, the better fit's own residual scatter."""
    pieces_a, pieces_b = segments.pieces(a), segments.pieces(b)
    if not pieces_a or pieces_b is None or len(pieces_a) != len(pieces_b):
        return None
    if any(np.shape(ra) != np.shape(rb) for (ra, _), (rb, _) in zip(pieces_a, pieces_b)):
        return None
    scale = (
        sigma
        if sigma and math.isfinite(sigma) and sigma > 0
        else math.sqrt(min(a.full.sse, b.full.sse) / max(a.full.residual_count, 1))
    )
    evidence = segment_evidence(pieces_a, pieces_b, scale, segments.kinds)
    how = decision(a, b, evidence.llr, min_gain, bic_margin)
    return Twins((a.label, b.label), members(a, b), evidence, how, None)


def weigh(
    chosen: Candidate,
    pairs: Sequence[tuple[Candidate, Candidate]],
    candidates: Sequence[Candidate],
    baseline: Candidate,
    segments: Segments,
    sigma: float | None,
    min_gain: float = explain.MIN_GAIN,
    bic_margin: float = explain.BIC_MARGIN,
) -> tuple[Candidate, list[Twins]]:
    """The evidence between each pair of twins the library found (the chosen set first, or, when nothing
    is chosen, the two best); where held-out error and BIC cannot separate the chosen set from its twin
    and the LLR can, the LLR's favourite is the answer, if it could be chosen at all (:func:`eligible`).
    Costs no simulation: the fits keep their residuals."""
    looks: list[Twins] = []
    answer = chosen
    for a, b in pairs:
        look = weighed(a, b, segments, sigma, min_gain, bic_margin)
        if look is None:
            continue
        if (
            look.decision == DECIDED_BY_LLR
            and chosen.ids
            and look.evidence.llr < 0
            and a is answer
            and eligible(b, candidates, baseline, min_gain, bic_margin)
        ):
            answer = b
        looks.append(look)
    for look in looks:
        look.chosen = answer.label if answer.ids else None
    return answer, looks
