"""The linearised screen: every pair, and triples of the best pairs, predicted from the residuals linearised
at a few fitted points.

Why: the Jacobian of the residuals with respect to every hypothesis' parameters is taken at a few fitted
points, the *anchors*: ``none`` and the best single hypotheses, whether or not they passed on their own,
since masking is exactly when they fail. An anchor's fit already holds the columns of its own parameters;
one perturbation per other parameter, all anchors in one sweep, gives the rest. From that, the best linear
correction for any set of hypotheses, the calibrated parameters refitted with it, is a bounded linear
least-squares problem that takes microseconds, so every pair can be tried.

A linearisation is only a guide (a 0.4 s lag is far from a 0.02 s step), so every prediction is checked by
simulating it, the whole step and half of it, in one more sweep, and the sets are ranked by the BIC of the
better real SSE. A parameter switched off by an infinite value at an anchor (a bound nobody reaches) has no
slope there: it is linearised only at an anchor that fitted it.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ....sweeps.domain import Point
from ....sweeps.fit import FitResult, Parameter, Residuals
from .. import explain
from ..engine import Fits, screen_sse
from ..linear_step import bounded_step
from .base import Screened, ScreenSettings, ScreenStrategy, Singles, combinable, parameter_count

ANCHORS = 2  # best single hypotheses (by full-fit SSE) linearised at, besides none
EXTENDED = 3  # best pairs (by predicted BIC) extended by one member into triples
POOR = 2.0  # the best set's real SSE above this many times its prediction: the linearisation is poor ...
MORE_PAIRS = 2  # ... and this many more pairs are shortlisted
Catalogue = dict[str, tuple[str, Parameter]]  # parameter name -> (hypothesis id, "" if calibrated; it)


def catalogue(fits: Fits, ids: Sequence[str]) -> Catalogue:
    """Every parameter a screened set may move: the calibrated ones and each hypothesis' own, as the library
    declares them."""
    entries: Catalogue = {p.name: ("", p) for p in fits.base}
    for hid in ids:
        entries.update({p.name: (hid, p) for p in fits.library[hid].parameters})
    return entries


@dataclass(frozen=True)
class Anchor:
    """A fitted set the screen extrapolates from."""

    ids: tuple[str, ...]
    fit: FitResult  # on every run, with its final Jacobian and residuals


def anchors(fits: Singles) -> list[Anchor]:
    """``none`` and the ANCHORS single hypotheses that fit best on every run, passed on their own or not."""
    singles = sorted((ids for ids in fits if len(ids) == 1), key=lambda ids: fits[ids].sse)
    return [Anchor(ids, fits[ids]) for ids in [(), *singles[:ANCHORS]] if ids in fits]


@dataclass(frozen=True)
class Linearisation:
    """The residuals on every run (stacked) about an anchor's fitted point, and their derivatives."""

    anchor: tuple[str, ...]
    point: Point  # the anchor's fitted point: every variable of the space
    names: tuple[str, ...]  # one per column
    owners: tuple[str, ...]  # per column: the hypothesis it belongs to, "" for a calibrated parameter
    jacobian: np.ndarray  # residuals x columns
    residuals: np.ndarray

    @property
    def sse(self) -> float:
        return float(self.residuals @ self.residuals)


def _step(value: float, parameter: Parameter) -> float:
    """One finite-difference step, inward at an upper bound, as the fits take them."""
    return parameter.step if value + parameter.step <= parameter.upper else -parameter.step


def probes(anchor: Anchor, extra: Sequence[Parameter]) -> list[Point]:
    """The anchor's point moved by one step in each parameter it does not fit: the missing columns."""
    moved = []
    for p in extra:
        value = anchor.fit.point.get(p.name, 0.0)
        moved.append({**anchor.fit.point, p.name: value + _step(value, p)})
    return moved


def extra_parameters(anchor: Anchor, entries: Catalogue) -> list[Parameter]:
    """The hypotheses' parameters of the catalogue that the anchor's fit does not already move, and that have
    a slope there (a finite value)."""
    return [
        p
        for name, (owner, p) in entries.items()
        if owner and name not in anchor.fit.names and math.isfinite(anchor.fit.point.get(name, 0.0))
    ]


def linearise(
    anchor: Anchor, entries: Catalogue, scenarios: Sequence[str], residuals: Residuals
) -> Linearisation:
    """The anchor's own Jacobian with a column for every other parameter, from the residuals of
    :func:`probes` (a probe that failed to simulate gives a zero column, as in the fits)."""
    fit = anchor.fit
    base = fit.residuals
    columns = [np.vstack(fit.jacobian)] if fit.names else []
    extra = extra_parameters(anchor, entries)
    for p, point in zip(extra, probes(anchor, extra)):
        delta = point[p.name] - fit.point.get(p.name, 0.0)
        moved = [residuals(point, s) for s in scenarios]
        column = [np.zeros_like(r) if m is None else (m - r) / delta for m, r in zip(moved, base)]
        columns.append(np.concatenate(column)[:, None])
    names = (*fit.names, *(p.name for p in extra))
    return Linearisation(
        anchor.ids,
        dict(fit.point),
        names,
        tuple(entries[n][0] for n in names),
        np.hstack(columns),
        np.concatenate(base),
    )


def predict(lin: Linearisation, ids: tuple[str, ...], entries: Catalogue) -> tuple[dict[str, float], float]:
    """The bounded least-squares step for the set ``ids`` (a superset of the anchor's) with the calibrated
    parameters free too, and the SSE the linearisation predicts for it (linear_step.bounded_step). Columns
    are scaled by their finite-difference steps, so that millimetres of antenna and hundreds of kilograms
    weigh alike."""
    free = [k for k, owner in enumerate(lin.owners) if not owner or owner in ids]
    params = [entries[lin.names[k]][1] for k in free]
    x = np.array([lin.point.get(p.name, 0.0) for p in params])
    lower = np.minimum(np.array([p.lower for p in params]) - x, 0.0)  # a point just outside stays feasible
    upper = np.maximum(np.array([p.upper for p in params]) - x, 0.0)
    steps = np.array([p.step for p in params])
    delta, sse = bounded_step(lin.jacobian[:, free], lin.residuals, lower, upper, steps)
    return {p.name: float(d) for p, d in zip(params, delta)}, sse


def anchor_of(ids: tuple[str, ...], anchors: Sequence[Anchor]) -> Anchor:
    """The largest fitted anchor inside ``ids``, the better fitting of equals (none is inside every set)."""
    inside = [a for a in anchors if set(a.ids) <= set(ids)]
    return min(inside, key=lambda a: (-len(a.ids), a.fit.sse))


def pairs_of(ids: Sequence[str]) -> list[tuple[str, ...]]:
    return list(itertools.combinations(ids, 2))


def triples_of(pairs: Sequence[tuple[str, ...]], ids: Sequence[str]) -> list[tuple[str, ...]]:
    """Each pair extended by one more member, in the order of ``ids``, each triple once."""
    order = {h: k for k, h in enumerate(ids)}
    found = {tuple(sorted({*pair, h}, key=order.__getitem__)) for pair in pairs for h in ids if h not in pair}
    return sorted(found, key=lambda t: [order[h] for h in t])


def trial_points(lin: Linearisation, delta: Mapping[str, float]) -> list[Point]:
    """The predicted point and half-way to it: a linearisation overshoots on strongly curved effects."""
    return [{**lin.point, **{n: lin.point.get(n, 0.0) + f * d for n, d in delta.items()}} for f in (1.0, 0.5)]


class Linearised(ScreenStrategy):
    """Every pair, and triples of the best, linearised at none and the best singles (module docstring): the
    Robotti's."""

    name = "linearised"
    how = (
        "the residuals linearised at none and the best single fits, whether or not they passed alone (masked "
        "effects do not); each combination's bounded least-squares step, the calibrated parameters free too, "
        "predicts its SSE, and simulating the step and half of it gives the SSE it really reaches"
    )
    shortlisted = ScreenSettings(pairs=3, triples=2, limit=5)

    def screened(self, fits: Fits, singles: Singles, settings: ScreenSettings) -> tuple[list[Screened], int]:
        """Two sweeps in all: the probes of every anchor, then the trial points of every set."""
        ids = [h for h in fits.library if (h,) in singles]
        entries = catalogue(fits, ids)
        at = anchors(singles)
        extra = {a.ids: extra_parameters(a, entries) for a in at}
        moved = fits.evaluate([p for a in at for p in probes(a, extra[a.ids])])
        lins = {a.ids: linearise(a, entries, fits.scenarios, moved) for a in at}

        def predicted(s: tuple[str, ...]) -> tuple[dict[str, float], float]:
            return predict(lins[anchor_of(s, at).ids], s, entries)

        sets = [s for s in pairs_of(ids) if combinable(fits, s)]
        prediction = {s: predicted(s) for s in sets}
        n = len(next(iter(lins.values())).residuals)
        if settings.triples:
            best = sorted(sets, key=lambda s: explain.bic_of(prediction[s][1], n, parameter_count(fits, s)))
            for s in triples_of(best[:EXTENDED], ids):
                if combinable(fits, s):
                    prediction[s] = predicted(s)
        trials = {s: trial_points(lins[anchor_of(s, at).ids], prediction[s][0]) for s in prediction}
        checked = fits.evaluate([p for points in trials.values() for p in points])
        result = []
        for s, (_, sse_predicted) in prediction.items():
            lin = lins[anchor_of(s, at).ids]
            tried = [(lin.sse, lin.point)] + [(screen_sse(p, fits.scenarios, checked), p) for p in trials[s]]
            sse, start = min(tried, key=lambda t: t[0])
            bic = explain.bic_of(sse, n, parameter_count(fits, s))
            result.append(Screened(s, lin.anchor, sse_predicted, sse, bic, start))
        return sorted(result, key=lambda x: x.bic), len(prediction)

    def shortlist(
        self, screened: Sequence[Screened], settings: ScreenSettings, look_alikes: Mapping[str, Sequence[str]]
    ) -> list[Screened]:
        """The default shortlist, with MORE_PAIRS more pairs when the best set's real SSE is more than POOR
        times its prediction: the linearisation is poor there, and its ranking with it."""
        if screened and screened[0].sse > POOR * screened[0].predicted_sse:
            settings = replace(settings, pairs=settings.pairs + MORE_PAIRS)
        return super().shortlist(screened, settings, look_alikes)
