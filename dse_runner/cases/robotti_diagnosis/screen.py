"""Screen: every pair of hypotheses, and triples of the best pairs, judged before any of them is fitted.

Fitting every combination for real (a full fit and a fit per fold each) would cost some ten times
the singles. Instead, the Jacobian of the fix residuals with respect to every effect parameter is
taken at a few fitted points, the *anchors*: ``none`` and the two best single effects, whether or
not they passed on their own, since masking is exactly when they fail. An anchor's fit already
holds the columns of its own parameters; one perturbation per other effect parameter, all anchors
in one sweep, gives the rest. From that, the best linear correction for any set of effects, the
calibrated parameters re-fitted with it, is a bounded linear least-squares problem that takes
microseconds, so every pair can be tried.

A linearisation is only a guide (a 0.4 s lag is far from a 0.02 s step), so every prediction is
checked by simulating it, the whole step and half of it, in one more sweep, and the sets are
ranked by the BIC of the better real SSE. Only a short list is fitted for real, each from its
checked point, with the look-alikes of the sets on it beside them.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from ...analysis.diagnose import explain
from ...sweeps.domain import Point
from ...sweeps.fit import FitResult, Parameter, Residuals
from .hypotheses import LOOK_ALIKES, hypothesis

ANCHORS = 2  # best single effects (by full-fit SSE) linearised at, besides none
EXTENDED = 3  # best pairs (by predicted BIC) extended by one effect into triples
Evaluate = Callable[[list[Point]], Residuals]  # run the points on every run in one sweep; their residuals
Catalogue = dict[
    str, tuple[str, Parameter]
]  # parameter name -> (hypothesis id, "" if calibrated; its bounds)


def catalogue(base: Sequence[Parameter], vehicle: str, ids: Sequence[str]) -> Catalogue:
    """Every parameter a screened set may move: the calibrated ones and each hypothesis' effect parameters."""
    entries: Catalogue = {p.name: ("", p) for p in base}
    for hid in ids:
        for p in hypothesis(hid).parameters:
            name = f"{vehicle}.{p.variable}"
            entries[name] = (hid, Parameter(name, 0.0, p.lower, p.upper, p.step))
    return entries


@dataclass(frozen=True)
class Anchor:
    """A fitted set the screen extrapolates from."""

    ids: tuple[str, ...]
    fit: FitResult  # on every run, with its final Jacobian and residuals


def anchors(fits: dict[tuple[str, ...], FitResult]) -> list[Anchor]:
    """``none`` and the ANCHORS single effects that fit best on every run, passed on their own or not."""
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


@dataclass(frozen=True)
class Screened:
    """A set of effects as the screen saw it: the linear prediction and what simulating it gave."""

    ids: tuple[str, ...]
    anchor: tuple[str, ...]
    predicted_sse: float
    sse: float  # the best real SSE of the anchor, the predicted point and half-way to it
    bic: float  # of ``sse``, charged for every parameter the set fits
    start: Point  # where that SSE was found: the set's full fit starts there

    @property
    def label(self) -> str:
        return "+".join(self.ids)


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
    """The effect parameters of the catalogue that the anchor's fit does not already move."""
    return [p for name, (owner, p) in entries.items() if owner and name not in anchor.fit.names]


def linearise(
    anchor: Anchor, entries: Catalogue, scenarios: Sequence[str], residuals: Residuals
) -> Linearisation:
    """The anchor's own Jacobian with a column for every other effect parameter, from the residuals of
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
    parameters free too, and the SSE the linearisation predicts for it. Columns are scaled by their
    finite-difference steps, so that millimetres of antenna and hundreds of kilograms weigh alike."""
    free = [k for k, owner in enumerate(lin.owners) if not owner or owner in ids]
    params = [entries[lin.names[k]][1] for k in free]
    x = np.array([lin.point.get(p.name, 0.0) for p in params])
    steps = np.array([p.step for p in params])
    lower = (np.array([p.lower for p in params]) - x) / steps
    upper = (np.array([p.upper for p in params]) - x) / steps
    lower, upper = np.minimum(lower, 0.0), np.maximum(upper, 0.0)  # a point just outside stays feasible
    scaled = lin.jacobian[:, free] * steps
    solved = lsq_linear(scaled, -lin.residuals, bounds=(lower, upper), method="bvls")
    delta = solved.x * steps
    predicted = lin.residuals + lin.jacobian[:, free] @ delta
    return {p.name: float(d) for p, d in zip(params, delta)}, float(predicted @ predicted)


def anchor_of(ids: tuple[str, ...], anchors: Sequence[Anchor]) -> Anchor:
    """The largest fitted anchor inside ``ids``, the better fitting one of
    equals (none is inside every set)."""
    inside = [a for a in anchors if set(a.ids) <= set(ids)]
    return min(inside, key=lambda a: (-len(a.ids), a.fit.sse))


def pairs_of(ids: Sequence[str]) -> list[tuple[str, ...]]:
    return list(itertools.combinations(ids, 2))


def triples_of(pairs: Sequence[tuple[str, ...]], ids: Sequence[str]) -> list[tuple[str, ...]]:
    """Each pair extended by one more effect, in the order of ``ids``, each triple once."""
    order = {h: k for k, h in enumerate(ids)}
    found = {tuple(sorted({*pair, h}, key=order.__getitem__)) for pair in pairs for h in ids if h not in pair}
    return sorted(found, key=lambda t: [order[h] for h in t])


def trial_points(lin: Linearisation, delta: dict[str, float]) -> list[Point]:
    """The predicted point and half-way to it: a linearisation overshoots on strongly curved effects."""
    return [{**lin.point, **{n: lin.point.get(n, 0.0) + f * d for n, d in delta.items()}} for f in (1.0, 0.5)]


def real_sse(point: Point, scenarios: Sequence[str], residuals: Residuals) -> float:
    """The SSE of a simulated point on every run; infinite if any run failed."""
    found = [residuals(point, s) for s in scenarios]
    return math.inf if any(r is None for r in found) else float(sum(r @ r for r in found))


def screen(
    anchors: Sequence[Anchor],
    ids: Sequence[str],
    entries: Catalogue,
    scenarios: Sequence[str],
    evaluate: Evaluate,
    triples: bool = True,
) -> list[Screened]:
    """Every pair of ``ids``, and (with ``triples``) the triples extending the best predicted pairs, each
    predicted from its anchor and checked by simulation: best verified BIC first. Two sweeps in all."""
    extra = {a.ids: extra_parameters(a, entries) for a in anchors}
    moved = evaluate([p for a in anchors for p in probes(a, extra[a.ids])])
    lins = {a.ids: linearise(a, entries, scenarios, moved) for a in anchors}
    sets = pairs_of(ids)
    predicted = {s: predict(lins[anchor_of(s, anchors).ids], s, entries) for s in sets}
    n = len(next(iter(lins.values())).residuals)
    if triples:
        best = sorted(sets, key=lambda s: explain.bic_of(predicted[s][1], n, _parameters(s, entries)))
        for s in triples_of(best[:EXTENDED], ids):
            predicted[s] = predict(lins[anchor_of(s, anchors).ids], s, entries)
    trials = {s: trial_points(lins[anchor_of(s, anchors).ids], predicted[s][0]) for s in predicted}
    checked = evaluate([p for points in trials.values() for p in points])
    result = []
    for s, (_, sse_predicted) in predicted.items():
        lin = lins[anchor_of(s, anchors).ids]
        tried = [(lin.sse, lin.point)] + [(real_sse(p, scenarios, checked), p) for p in trials[s]]
        sse, start = min(tried, key=lambda t: t[0])
        result.append(
            Screened(
                s, lin.anchor, sse_predicted, sse, explain.bic_of(sse, n, _parameters(s, entries)), start
            )
        )
    return sorted(result, key=lambda x: x.bic)


def _parameters(ids: tuple[str, ...], entries: Catalogue) -> int:
    """How many parameters a set fits: the calibrated ones and its effects'."""
    return sum(1 for owner, _ in entries.values() if not owner or owner in ids)


def shortlist(screened: Sequence[Screened], pairs: int, triples: int, limit: int) -> list[Screened]:
    """The sets worth fitting for real, at most ``limit``: the best ``pairs`` pairs, the best ``triples``
    triples, then the look-alike swaps of those (one member replaced by its twin, if that set was screened),
    best verified BIC first. When the best set's real SSE is more than twice its prediction the
    linearisation is poor, and two more pairs are taken."""
    if not screened:
        return []
    top = screened[0]
    if top.sse > 2.0 * top.predicted_sse:
        pairs += 2
    chosen = [s for s in screened if len(s.ids) == 2][:pairs] + [s for s in screened if len(s.ids) == 3][
        :triples
    ]
    by_ids = {frozenset(s.ids): s for s in screened}
    twins = [by_ids[swap] for s in chosen for swap in swaps(s.ids) if swap in by_ids]
    result: list[Screened] = []
    for s in chosen + sorted(twins, key=lambda x: x.bic):
        if s not in result and len(result) < limit:
            result.append(s)
    return result


def swaps(ids: tuple[str, ...]) -> list[frozenset[str]]:
    """The sets with one member of ``ids`` replaced by one of its look-alikes."""
    return [frozenset(set(ids) - {m} | {t}) for m in ids for t in LOOK_ALIKES.get(m, ()) if t not in ids]
