"""Pairs of signal effects, screened from the single fits before any pair is fitted.

Why: a space has four effects per signal, so 8 effects and 28 pairs for a model with one input and one
compared output, and many more with more signals; fitting each for real (a fit on every run and one per fold)
would cost ten times the singles. Instead each single's fit is taken as a direction: how its fitted effect,
with the calibration refitted alongside, changed the residuals from those of ``none``. A pair is predicted as
the best mixture of its two directions plus a small change of the calibrated parameters (``none``'s own
Jacobian), a least-squares problem of a few columns that costs microseconds: every pair is predicted, no
simulation needed. That is exact when the two effects superpose, and only a guide when they do not (a delay's
direction is far from linear), so the best predicted pairs, and every pair of the best singles, are checked by
simulating their mixed point and the plain sum of both singles' changes, in one sweep; the best by the BIC of
that real error are fitted for real, from the better point.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ...sweeps.domain import Point
from ...sweeps.fit import FitResult, Parameter
from . import explain

PREDICTED = 6  # best pairs by predicted BIC that are checked by simulation
BEST_SINGLES = 3  # every pair of this many best singles (by their SSE) is checked too
SHORTLIST = 3  # checked pairs, best real BIC first, that are fitted for real
RealSse = Callable[[list[Point]], list[float]]  # simulate points on every run in one sweep: their SSE


@dataclass(frozen=True)
class ScreenedPair:
    """A pair as the screen saw it: its predicted SSE, and the real SSE at the better of its trial points."""

    ids: tuple[str, str]
    weights: tuple[float, float]  # how much of each single's change the prediction mixes in
    predicted_sse: float
    sse: float
    bic: float
    start: Point  # where a real fit starts

    @property
    def label(self) -> str:
        return "+".join(self.ids)

    def to_json(self) -> dict[str, object]:
        return {
            "id": self.label,
            "weights": list(self.weights),
            "predicted_sse": self.predicted_sse,
            "sse": self.sse,
            "bic": self.bic,
        }


def stacked(fit: FitResult) -> np.ndarray:
    return np.concatenate(fit.residuals) if fit.residuals else np.zeros(0)


def prediction(none: FitResult, a: FitResult, b: FitResult) -> tuple[np.ndarray, float]:
    """The least-squares mixture of the singles' changes ``a`` and ``b`` (and a change of the calibrated
    parameters along ``none``'s Jacobian): the coefficients [calibrated..., weight a, weight b] and the
    SSE it predicts."""
    r0 = stacked(none)
    columns = [np.vstack(none.jacobian)] if none.names else []
    columns += [(stacked(a) - r0)[:, None], (stacked(b) - r0)[:, None]]
    matrix = np.hstack(columns)
    scale = np.linalg.norm(matrix, axis=0)
    scale[scale == 0] = 1.0
    solved, *_ = np.linalg.lstsq(matrix / scale, -r0, rcond=None)
    coefficients = solved / scale
    predicted = r0 + matrix @ coefficients
    return coefficients, float(predicted @ predicted)


def mixed(
    none: FitResult,
    a: FitResult,
    b: FitResult,
    coefficients: Sequence[float],
    bounds: Mapping[str, Parameter],
) -> Point:
    """The point a prediction stands for: ``none``'s plus each single's change by its weight, plus the
    calibrated change, held within every parameter's bounds."""
    *calibrated, wa, wb = coefficients
    point = dict(none.point)
    for name in {*a.point, *b.point}:
        base = none.point.get(name, 0.0)
        value_a, value_b = a.point.get(name, base), b.point.get(name, base)
        if not math.isfinite(
            base
        ):  # a bound absent from none (state_max at inf) is the single's own, unweighted
            point[name] = float(value_a if value_a != base else value_b)
            continue
        point[name] = float(base + wa * (value_a - base) + wb * (value_b - base))
    for name, change in zip(none.names, calibrated):
        point[name] = float(point[name] + change)
    return clipped(point, bounds)


def clipped(point: Point, bounds: Mapping[str, Parameter]) -> Point:
    return {
        n: float(np.clip(v, bounds[n].lower, bounds[n].upper)) if n in bounds else v for n, v in point.items()
    }


def to_check(
    singles: Mapping[str, FitResult],
    predicted: Mapping[tuple[str, str], float],
    parameters: Callable[[tuple[str, str]], int],
    n: int,
) -> list[tuple[str, str]]:
    """The pairs checked by simulation: every pair of the best singles, and the best predicted ones."""
    best = sorted(singles, key=lambda h: singles[h].sse)[:BEST_SINGLES]
    chosen = [tuple(sorted(p)) for p in itertools.combinations(best, 2) if tuple(sorted(p)) in predicted]
    ranked = sorted(predicted, key=lambda p: explain.bic_of(predicted[p], n, parameters(p)))
    for pair in ranked[:PREDICTED]:
        if pair not in chosen:
            chosen.append(pair)
    return chosen  # type: ignore[return-value]


def screen(
    none: FitResult, singles: Mapping[str, FitResult], bounds: Mapping[str, Parameter], real_sse: RealSse
) -> tuple[list[ScreenedPair], int]:
    """Every pair of ``singles`` that fit no parameter in common predicted, the best checked in one sweep:
    the checked pairs, best real BIC first, and how many pairs were predicted."""
    n = len(stacked(none))
    calibrated = len(none.names)
    own = {h: set(f.names) - set(none.names) for h, f in singles.items()}  # each effect's own parameters

    def parameters(pair: tuple[str, str]) -> int:
        return calibrated + len(own[pair[0]] | own[pair[1]])

    pairs = [tuple(sorted(p)) for p in itertools.combinations(singles, 2) if not own[p[0]] & own[p[1]]]
    solved = {p: prediction(none, singles[p[0]], singles[p[1]]) for p in pairs}
    checked = to_check(singles, {p: s for p, (_, s) in solved.items()}, parameters, n)
    trials = {}
    for pair in checked:
        a, b = singles[pair[0]], singles[pair[1]]
        plain = [0.0] * calibrated + [1.0, 1.0]
        trials[pair] = [mixed(none, a, b, solved[pair][0], bounds), mixed(none, a, b, plain, bounds)]
    sses = real_sse([p for points in trials.values() for p in points])
    found, k = [], 0
    for pair in checked:
        tried = list(zip(sses[k : k + 2], trials[pair]))
        k += 2
        sse, start = min(tried, key=lambda t: t[0])
        weights = tuple(float(w) for w in solved[pair][0][-2:])
        found.append(
            ScreenedPair(
                pair,
                weights,
                solved[pair][1],
                sse,  # type: ignore[arg-type]
                explain.bic_of(sse, n, parameters(pair)),
                start,
            )
        )
    return sorted(found, key=lambda s: s.bic), len(pairs)


def shortlist(screened: Sequence[ScreenedPair], count: int = SHORTLIST) -> list[ScreenedPair]:
    """The pairs worth a real fit: the best real BIC, those whose simulation succeeded."""
    return [s for s in screened if math.isfinite(s.sse)][:count]
