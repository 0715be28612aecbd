"""The mixed screen: combinations predicted as mixtures of their members' single fits.

Why: each single's fit is taken as a direction, how its fitted effect, with the calibration refitted
alongside, changed the residuals from those of ``none``. A combination is predicted as the best mixture of
its members' directions plus a small change of the calibrated parameters (``none``'s own Jacobian), a
least-squares problem of a few columns that costs microseconds: every pair is predicted, with no
simulation beyond the singles'. That is exact when the effects superpose, and only a guide when they do not
(a delay's direction is far from linear), so the best predicted pairs, and every pair of the best singles,
are checked by simulating their mixed point and the plain sum of their members' changes, in one sweep.
With triples asked for, the best checked pairs are extended by a third member each, predicted the same way,
and the best of those checked in a second sweep.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ....sweeps.domain import Point
from ....sweeps.fit import FitResult, Parameter
from .. import explain
from ..engine import Fits, screen_sse
from .base import Screened, ScreenSettings, ScreenStrategy, Singles, combinable, parameter_count

PREDICTED = 6  # best combinations of each size by predicted BIC that are checked by simulation
BEST_SINGLES = 3  # every pair of this many best singles (by their SSE) is checked too
EXTENDED = 3  # best checked pairs (by real BIC) extended by one more member into triples


def stacked(fit: FitResult) -> np.ndarray:
    return np.concatenate(fit.residuals) if fit.residuals else np.zeros(0)


def prediction(none: FitResult, members: Sequence[FitResult]) -> tuple[np.ndarray, float]:
    """The least-squares mixture of the members' changes (and a change of the calibrated parameters along
    ``none``'s Jacobian): the coefficients [calibrated..., one weight per member] and the SSE it predicts."""
    r0 = stacked(none)
    columns = [np.vstack(none.jacobian)] if none.names else []
    columns += [(stacked(m) - r0)[:, None] for m in members]
    matrix = np.hstack(columns)
    scale = np.linalg.norm(matrix, axis=0)
    scale[scale == 0] = 1.0
    solved, *_ = np.linalg.lstsq(matrix / scale, -r0, rcond=None)
    coefficients = solved / scale
    predicted = r0 + matrix @ coefficients
    return coefficients, float(predicted @ predicted)


def mixed(
    none: FitResult,
    members: Sequence[FitResult],
    coefficients: Sequence[float],
    bounds: Mapping[str, Parameter],
) -> Point:
    """The point a prediction stands for: ``none``'s plus each member's change by its weight, plus the
    calibrated change, held within every parameter's bounds."""
    calibrated, weights = coefficients[: len(coefficients) - len(members)], coefficients[-len(members) :]
    point = dict(none.point)
    for name in {n for m in members for n in m.point}:
        base = none.point.get(name, 0.0)
        values = [m.point.get(name, base) for m in members]
        if not math.isfinite(
            base
        ):  # a bound absent from none (state_max at inf) is the member's own, unweighted
            point[name] = float(next((v for v in values if v != base), values[-1]))
            continue
        value = base
        for weight, v in zip(weights, values):
            value = value + weight * (v - base)
        point[name] = float(value)
    for name, change in zip(none.names, calibrated):
        point[name] = float(point[name] + change)
    return clipped(point, bounds)


def clipped(point: Point, bounds: Mapping[str, Parameter]) -> Point:
    return {
        n: float(np.clip(v, bounds[n].lower, bounds[n].upper)) if n in bounds else v for n, v in point.items()
    }


def to_check(
    singles: Mapping[str, FitResult],
    predicted: Mapping[tuple[str, ...], float],
    bic: Mapping[tuple[str, ...], float],
) -> list[tuple[str, ...]]:
    """The pairs checked by simulation: every pair of the best singles, and the best predicted ones."""
    best = sorted(singles, key=lambda h: singles[h].sse)[:BEST_SINGLES]
    chosen = [tuple(sorted(p)) for p in itertools.combinations(best, 2) if tuple(sorted(p)) in predicted]
    for pair in sorted(predicted, key=bic.__getitem__)[:PREDICTED]:
        if pair not in chosen:
            chosen.append(pair)
    return chosen


def extended(pairs: Sequence[tuple[str, ...]], members: Sequence[str], fits: Fits) -> list[tuple[str, ...]]:
    """Each pair with one more member that can join it, each triple once, its members in name order."""
    found = {tuple(sorted((*pair, h))) for pair in pairs for h in members if h not in pair}
    return sorted(t for t in found if combinable(fits, t))


Solved = dict[tuple[str, ...], tuple[np.ndarray, float]]  # set -> (its coefficients, the SSE predicted)


@dataclass(frozen=True)
class Directions:
    """What combinations are mixed from: none's fit and each single's (a failed one has no direction)."""

    fits: Fits
    none: FitResult
    members: Mapping[str, FitResult]

    @classmethod
    def of(cls, fits: Fits, singles: Singles) -> Directions:
        members = {s[0]: fit for s, fit in singles.items() if s and fit.error is None}
        return cls(fits, singles[()], members)

    @property
    def n(self) -> int:
        return len(stacked(self.none))

    def bic(self, ids: tuple[str, ...], sse: float) -> float:
        return explain.bic_of(sse, self.n, parameter_count(self.fits, ids))

    def predicted(self, sets: Sequence[tuple[str, ...]]) -> Solved:
        return {s: prediction(self.none, [self.members[h] for h in s]) for s in sets}

    def checked(self, sets: Sequence[tuple[str, ...]], solved: Solved) -> list[Screened]:
        """Each set's mixed point and the plain sum of its members' changes, simulated in one sweep: the
        better one."""
        fits, none = self.fits, self.none
        bounds = {p.name: p for p in (*fits.base, *(p for h in fits.library.values() for p in h.parameters))}
        trials = {}
        for s in sets:
            members = [self.members[h] for h in s]
            plain = [0.0] * len(none.names) + [1.0] * len(s)
            trials[s] = [mixed(none, members, solved[s][0], bounds), mixed(none, members, plain, bounds)]
        residuals = fits.evaluate([p for points in trials.values() for p in points])
        found = []
        for s in sets:
            tried = [(screen_sse(p, fits.scenarios, residuals), p) for p in trials[s]]
            sse, start = min(tried, key=lambda t: t[0])
            weights = tuple(float(w) for w in solved[s][0][-len(s) :])
            found.append(Screened(s, (), solved[s][1], sse, self.bic(s, sse), start, weights))
        return found


class Mixed(ScreenStrategy):
    """Combinations as mixtures of their members' single fits (module docstring): the signal library's."""

    name = "mixed"
    how = (
        "each combination predicted as a mixture of its members' single fits (how much of each member's own "
        "change of the residuals it takes), the best checked by simulation"
    )
    # pairs only by default: extended into triples it shortlisted a third member the clipped force of
    # test_signal_blind does not have (input_square beside its two bounds, which the answer then kept), and
    # an answer grows one member at a time anyway (engine.grown), each cross-validated
    shortlisted = ScreenSettings(pairs=3, triples=0, limit=3)

    def screened(self, fits: Fits, singles: Singles, settings: ScreenSettings) -> tuple[list[Screened], int]:
        """One sweep for the pairs; with triples asked for, one more for them."""
        d = Directions.of(fits, singles)
        pairs = [tuple(sorted(p)) for p in itertools.combinations(d.members, 2) if combinable(fits, p)]
        solved = d.predicted(pairs)
        bic = {p: d.bic(p, sse) for p, (_, sse) in solved.items()}
        found = d.checked(to_check(d.members, {p: sse for p, (_, sse) in solved.items()}, bic), solved)
        count = len(pairs)
        if settings.triples:
            best = sorted((s for s in found if math.isfinite(s.sse)), key=lambda s: s.bic)[:EXTENDED]
            triples = extended([s.ids for s in best], list(d.members), fits)
            solved = d.predicted(triples)
            ranked = sorted(triples, key=lambda t: d.bic(t, solved[t][1]))
            found += d.checked(ranked[:PREDICTED], solved)
            count += len(triples)
        return sorted(found, key=lambda s: s.bic), count
